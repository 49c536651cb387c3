#pragma once
// The scene *description*: what a scene file says, independent of any acceleration structure
// (docs/design.md, S2: parsed description vs runtime scene). Loaders (MGF, OBJ,
// manifest) produce it; accel/ builds the Embree scene from it; the farm will ship the files
// it came from and let each worker rebuild it.
//
// Everything is triangles: MGF's curved primitives (sph, cyl, cone, ring, torus, prism) are
// tessellated by the loader with smooth vertex normals (see mgf_loader.h for the rule).

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/core/math.h"
#include "common/scene/environment.h"
#include "common/scene/metallic_roughness_params.h"
#include "common/scene/punctual_light.h"
#include "common/scene/texture.h"

namespace pf {

// Ward's reflection model plus transmission and emission (Wald 1999, §2.1; MGF `rd rs td ts
// ed ir`). All reflectances/transmittances are linear RGB in [0,1] per channel.
// Every member has an initializer, so a designated initializer (Material{.emission = ...}) may
// name only some of them.
struct Material {
  std::string name{};
  Rgb diffuse_reflectance{};            // ρd: Lambertian reflection.
  Rgb specular_reflectance{};           // ρs: mirror if specular_roughness == 0, else Ward lobe.
  float specular_roughness = 0.0f;      // Ward α of the reflection lobe (RMS slope).
  Rgb diffuse_transmittance{};          // τd: Lambertian transmission to the other side.
  Rgb specular_transmittance{};         // τs: specular transmission (refraction if ior != 1).
  float transmission_roughness = 0.0f;  // MGF ts α; rendered as perfect transmission (documented).
  float ior = 1.0f;                     // Index of refraction inside (behind the front face).
  Rgb emission{};                       // Le in W/(m²·sr), emitted from the front side only.
  bool one_sided = false;               // MGF `sides 1` (recorded; surfaces are shaded two-sided).
  // GGX microfacet lobes instead of Ward's (materials/bsdf_microfacet.h, docs/renderer.md
  // "Microfacet lobes"). kConductor: ρs is a rough metal with Schlick's F0 = ρs. kDielectric:
  // τs and ior are a rough glass (Walter et al. 2007; exact Fresnel). Roughness below 0.0316
  // (α = r² < 1e-3) is the smooth (delta) mirror / dielectric. kNone keeps Ward's model above.
  enum class Microfacet : uint8_t { kNone, kConductor, kDielectric };
  Microfacet microfacet = Microfacet::kNone;
  float microfacet_roughness = 0.0f;  // glTF perceptual roughness r in [0, 1]; GGX α = r².
  // The conductor's Schlick reflectance at grazing incidence, F = F0 + (F90 − F0)(1 − cos)⁵:
  // 1 for a metal; below 1 keeps a Lambertian lobe beside it energy-conserving (metallic_roughness.h).
  float microfacet_f90 = 1.0f;
  // An image texture (SceneDescription::textures index, −1: none) whose colour at the hit
  // multiplies the base colour (docs/renderer.md, "Textures"): for a material mapped from glTF's
  // metallic-roughness parameters (`metallic_roughness` set) the material is mapped again from
  // baseColorFactor × texel; otherwise (OBJ map_Kd) ρd is multiplied by the texel.
  int32_t base_color_texture = -1;
  // glTF's metallicRoughnessTexture (a textures index, −1: none; only with `metallic_roughness`):
  // its blue channel multiplies metallicFactor and its green roughnessFactor before the mapping
  // (docs/renderer.md, "Textures"). It reads the same texture coordinates as the base colour.
  int32_t metallic_roughness_texture = -1;
  // glTF's KHR_materials_transmission transmissionTexture (a textures index, −1: none; only with
  // `metallic_roughness`): its red channel multiplies transmissionFactor before the mapping
  // (docs/renderer.md, "Textures"), so it decides per texel between the opaque and the
  // transmissive mapping. It reads the same texture coordinates as the base colour.
  int32_t transmission_texture = -1;
  std::optional<MetallicRoughness> metallic_roughness{};  // the glTF parameters it was mapped from
  // An alpha-mask cut-out (glTF alphaMode MASK, OBJ map_d; docs/renderer.md, "Alpha masks"): the
  // surface is absent, for every ray, where alpha_factor × (alpha_texture's alpha at the hit, 1
  // without one) < alpha_cutoff. A cutoff of 0 (alpha is never below it) is an opaque surface.
  // An image texture (textures index, −1: none) multiplying the emission: Le(x) = emission ×
  // texel (glTF emissiveTexture, OBJ map_Ke; sRGB). Light sampling and photon emission stay
  // power-correct (lights/light_sampler.h).
  int32_t emission_texture = -1;
  float alpha_cutoff = 0.0f;
  float alpha_factor = 1.0f;
  int32_t alpha_texture = -1;

  bool IsEmissive() const { return !emission.IsBlack(); }
  bool HasAlphaMask() const { return alpha_cutoff > 0.0f; }
};

// Whether a material's BSDF varies over its surface (scene/surface_material.h builds it per hit).
inline bool IsTextured(const Material& material) {
  return material.base_color_texture >= 0 || material.metallic_roughness_texture >= 0 ||
         material.transmission_texture >= 0 || material.emission_texture >= 0;
}

inline constexpr uint32_t kNoLight = 0xffffffffu;

// A camera: pinhole, vertical field of view, image right = forward × up. Its points are world
// coordinates in double (a camera 4 m from a model at 1e6 m is not on the float lattice there);
// Camera (camera/camera.h) moves them into the scene's frame (scene_frame.h) and rounds them.
struct CameraSpec {
  std::string name = "default";
  Vec3d eye{0, 0, 0};
  Vec3d look_at{0, 0, -1};
  Vec3 up{0, 1, 0};
  float vfov_degrees = 45.0f;
  int width = 512;
  int height = 512;
};

// A key of a camera path (camera_path.h): the camera at frame `frame`.
struct CameraKey {
  int frame = 0;  // ≥ 0; a path's keys in strictly increasing frame order
  Vec3d eye;
  Vec3d look_at;
  std::optional<Vec3> up = std::nullopt;             // the base camera's when absent
  std::optional<float> vfov_degrees = std::nullopt;  // the base camera's when absent
};

// A camera moving through a static scene (camera_path.h; a manifest's "camera_path").
struct CameraPath {
  std::vector<CameraKey> keys;  // empty: no path
  int first_frame() const { return keys.empty() ? 0 : keys.front().frame; }
  int last_frame() const { return keys.empty() ? -1 : keys.back().frame; }
};

struct SceneDescription {
  // Triangle soup with shared vertices, in the scene's frame (scene_frame.h): positions[i] is
  // the world point origin + positions[i]. origin is 0 unless the scene is far from the world
  // origin; the loaders choose it in double before they round any coordinate to float.
  Vec3d origin;
  std::vector<Vec3> positions;
  // Per-vertex shading normals; empty, or one per position. A zero vector means "none":
  // triangles touching such a vertex use their geometric normal.
  std::vector<Vec3> normals;
  // Texture coordinates (texture.h's convention); empty, or one per position. Loaders read them
  // only when a material has a texture.
  std::vector<TextureCoordinates> uvs;
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<uint32_t> triangle_material;  // index into materials, one per triangle
  // Light id per triangle: every emitting source primitive (an MGF face or sphere, an OBJ
  // group with Ke) is one light, so that photons can be tagged with it (§4.2.3).
  std::vector<uint32_t> triangle_light;  // kNoLight for non-emitters
  uint32_t num_lights = 0;
  // Point, spot and directional lights (punctual_light.h), from a manifest's "lights"; each has
  // its own id after the emitting primitives' (num_lights counts them too).
  std::vector<PunctualLight> punctual_lights;
  // The sky (environment.h), from a manifest's "environment": one light more, its id the last.
  std::optional<Environment> environment;

  std::vector<Material> materials;
  std::vector<Texture> textures;      // Material's *_texture members index them
  std::vector<CameraSpec> cameras;    // from a manifest; may be empty
  CameraPath camera_path;             // a manifest's "camera_path"; no keys when it has none
  std::vector<std::string> warnings;  // non-fatal loader messages, "file:line: reason"
  std::string source;                 // the file it was loaded from
  // OBJ materials with Ka but no Ke: named when the scene has no light (Ka is not emission).
  std::vector<std::string> ambient_only_materials;

  size_t NumTriangles() const { return triangles.size(); }
  // In the scene's frame (add origin for world coordinates).
  Bounds3 ComputeBounds() const {
    Bounds3 b;
    for (const Vec3& p : positions) b.Extend(p);
    return b;
  }
  size_t NumEmissiveTriangles() const {
    size_t n = 0;
    for (uint32_t l : triangle_light) n += (l != kNoLight);
    return n;
  }
};

}  // namespace pf
