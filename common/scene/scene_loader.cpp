// Scene loading entry point: extension dispatch, manifest application, default camera.
#include "common/scene/scene_loader.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

#include "common/core/error.h"
#include "common/image/image_file.h"
#include "common/scene/gltf_loader.h"
#include "common/scene/material_kinds.h"
#include "common/scene/mgf_loader.h"
#include "common/scene/obj_loader.h"
#include "common/scene/scene_budget.h"
#include "common/scene/scene_reference.h"

namespace pf {
namespace {

constexpr const char* kSupported = "supported: .json (scene manifest), .mgf, .obj, .gltf, .glb";

std::string FormatNumber(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", v);
  return text;
}

Vec3d Abs(const Vec3d& v) {
  return {std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)};
}

std::string LowerExtension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

SceneDescription LoadGeometry(const std::filesystem::path& path, const std::filesystem::path& root,
                              PixelAllowance* texels) {
  const std::string ext = LowerExtension(path);
  if (ext == ".mgf") {
    MgfOptions options;
    options.include_root = root;
    return LoadMgf(path, options);
  }
  if (ext == ".obj") return LoadObj(path, root, {}, nullptr, texels);
  if (ext == ".gltf" || ext == ".glb") return LoadGltf(path, root, {}, texels);
  throw InputError(SourceLocation{path.string(), 0},
                   "unsupported scene file extension '" + ext + "' (" + kSupported + ")");
}

}  // namespace

void ApplyMaterialOverrides(const std::map<std::string, MaterialOverride>& overrides,
                            const std::string& manifest_file, SceneDescription* scene) {
  for (const auto& [name, o] : overrides) {
    const std::string key = "materials." + name;
    bool found = false;
    for (Material& m : scene->materials) {
      if (m.name != name) continue;
      found = true;
      if (const MaterialKind* kind = MaterialKinds().GetKind(o.kind)) kind->apply(&m);
      if (o.diffuse) m.diffuse_reflectance = *o.diffuse;
      if (o.specular) m.specular_reflectance = *o.specular;
      if (o.roughness)  // Ward α, or the GGX roughness r of a microfacet material (scene.h)
        (m.microfacet == Material::Microfacet::kNone ? m.specular_roughness : m.microfacet_roughness) =
            *o.roughness;
      if (o.transmission) m.specular_transmittance = *o.transmission;
      if (o.ior) m.ior = *o.ior;
      // A texture re-maps the glTF parameters per hit: they take the overridden roughness and ior
      // too (surface_material.h), or a textured hit would bring the file's values back.
      if (m.metallic_roughness) {
        if (o.roughness) m.metallic_roughness->roughness = *o.roughness;
        if (o.ior) m.metallic_roughness->ior = *o.ior;
      }
      // Overridden colours are this material's now: a texture multiplies the overridden ρd
      // (surface_material.h) instead of re-mapping the glTF parameters over the override.
      if (MaterialKinds().GetKind(o.kind) || o.diffuse || o.specular || o.transmission)
        m.metallic_roughness.reset();
      // A metallic-roughness texture re-maps metallic and roughness per hit: an override of
      // either (or of the parameters it maps from) stops it.
      if (!m.metallic_roughness || o.roughness) m.metallic_roughness_texture = -1;
      if (!m.metallic_roughness) m.transmission_texture = -1;
      if (o.emission) {
        if (!m.IsEmissive() || o.emission->IsBlack())
          throw InputError(SourceLocation{manifest_file, 0},
                           "key '" + key +
                               ".emission': can only change the emission of a "
                               "material that already emits, to a non-zero value (the geometry "
                               "loader decides which primitives are lights)");
        m.emission = *o.emission;
      }
      if (ClampEnergy(&m))
        scene->warnings.push_back(manifest_file + ": " + key +
                                  ": reflectance + transmittance exceeds 1 in some channel; "
                                  "scaled down to 1");
    }
    if (!found)
      throw InputError(SourceLocation{manifest_file, 0},
                       "key '" + key + "': the geometry has no material named \"" + name + "\"");
    // A `kind` re-decides the material, so the geometry loader's complaints about how it
    // mapped that material (e.g. "Tf ignored") no longer apply.
    if (o.kind != MaterialOverride::Kind::kUnchanged) {
      const std::string tag = "material '" + name + "': ";
      std::erase_if(scene->warnings, [&](const std::string& w) { return w.find(tag) != std::string::npos; });
    }
  }
}

void ApplyScale(double scale, const SourceLocation& where, const std::string& field,
                SceneDescription* scene) {
  if (scale == 1.0) return;
  auto fail = [&](const std::string& reason) {
    throw InputError(where, field + ": " + FormatNumber(scale) + " " + reason);
  };
  // World coordinates must stay finite floats (what Embree traces, docs/security.md "Limits"),
  // and a scale whose float is 0 or subnormal would collapse the scene.
  if (!(scale > 0.0) || !std::isfinite(scale)) fail("is not a finite number > 0");
  if (!(scale >= double(std::numeric_limits<float>::min()))) fail("is below the smallest normal float");
  const Bounds3 b = scene->ComputeBounds();
  if (!b.Empty()) {
    const Vec3d lo = Vec3d(b.lo) + scene->origin, hi = Vec3d(b.hi) + scene->origin;
    // Bounds the stored positions too: a far scene's are within half its extent of the origin.
    const double largest = MaxComponent(Max(Abs(lo), Abs(hi)));
    if (!(largest * scale <= double(std::numeric_limits<float>::max())))
      fail("makes vertex coordinates overflow a 32-bit float (largest |coordinate| " + FormatNumber(largest) +
           " x scale = " + FormatNumber(largest * scale) + ")");
  }
  for (size_t i = 0; i < scene->cameras.size(); ++i) {
    CameraSpec& c = scene->cameras[i];
    const std::string key = "cameras[" + std::to_string(i) + "]";
    for (const auto& [point, name] : {std::pair{&c.eye, ".eye"}, std::pair{&c.look_at, ".look_at"}}) {
      *point *= scale;
      if (!IsFinite(Vec3(*point)))
        fail("makes " + key + name + " overflow a 32-bit float (" + FormatNumber(MaxComponent(Abs(*point))) +
             ")");
    }
    if (!(LengthSquared(Vec3(c.look_at - c.eye)) > 0.0f))
      fail("makes " + key + ".look_at coincide with its eye");
  }
  for (size_t i = 0; i < scene->camera_path.keys.size(); ++i) {
    CameraKey& k = scene->camera_path.keys[i];
    const std::string key = "camera_path[" + std::to_string(i) + "]";
    for (const auto& [point, name] : {std::pair{&k.eye, ".eye"}, std::pair{&k.look_at, ".look_at"}}) {
      *point *= scale;
      if (!IsFinite(Vec3(*point)))
        fail("makes " + key + name + " overflow a 32-bit float (" + FormatNumber(MaxComponent(Abs(*point))) +
             ")");
    }
  }
  for (size_t i = 0; i < scene->punctual_lights.size(); ++i) {
    PunctualLight& l = scene->punctual_lights[i];
    l.position *= scale;
    if (!IsFinite(Vec3(l.position)))
      fail("makes lights[" + std::to_string(i) + "].position overflow a 32-bit float (" +
           FormatNumber(MaxComponent(Abs(l.position))) + ")");
  }
  scene->origin *= scale;
  for (Vec3& p : scene->positions) p = Vec3(Vec3d(p) * scale);
}

namespace {

SceneDescription LoadSceneFiles(const std::filesystem::path& path, double scale_override,
                                const std::filesystem::path& root_or_empty) {
  if (!std::isfinite(scale_override) || scale_override < 0.0)
    throw InputError("scale override must be a finite number > 0 (or 0 for none), got " +
                     std::to_string(scale_override));
  const std::filesystem::path root =
      !root_or_empty.empty() ? root_or_empty
                             : (path.has_parent_path() ? path.parent_path() : std::filesystem::path("."));
  // Every image of the load (its textures and its environment) is charged to one allowance.
  PixelAllowance texels(SceneBudget{}.max_texels);
  const std::string ext = LowerExtension(path);
  if (ext == ".mgf" || ext == ".obj" || ext == ".gltf" || ext == ".glb") {
    SceneDescription scene = LoadGeometry(path, root, &texels);
    if (scale_override > 0.0)
      ApplyScale(scale_override, SourceLocation{path.string(), 0}, "scale override", &scene);
    return scene;
  }
  if (ext != ".json")
    throw InputError(SourceLocation{path.string(), 0},
                     "unsupported scene file extension '" + ext + "' (" + kSupported + ")");

  const SceneManifest manifest = LoadManifest(path);
  const std::string manifest_file = path.string();
  // Confined before anything about the file is looked at (scene_reference.h).
  const std::string problem =
      SceneReferenceProblem(root, path.has_parent_path() ? path.parent_path() : std::filesystem::path("."),
                            manifest.geometry_reference, nullptr);
  if (!problem.empty())
    throw InputError(SourceLocation{manifest_file, manifest.geometry_line},
                     "key 'geometry': " + QuoteReference(manifest.geometry_reference) + " " + problem);
  const std::string geometry_ext = LowerExtension(manifest.geometry);
  if (geometry_ext != ".mgf" && geometry_ext != ".obj" && geometry_ext != ".gltf" && geometry_ext != ".glb")
    throw InputError(SourceLocation{manifest_file, 0},
                     "key 'geometry': '" + manifest.geometry.string() +
                         "' is not a geometry file (supported: .mgf, .obj, .gltf, .glb)");
  std::error_code ec;
  if (!std::filesystem::is_regular_file(manifest.geometry, ec))
    throw InputError(SourceLocation{manifest_file, 0},
                     "key 'geometry': file '" + manifest.geometry.string() + "' does not exist");

  SceneDescription scene = LoadGeometry(manifest.geometry, root, &texels);
  ApplyMaterialOverrides(manifest.materials, manifest_file, &scene);
  // A glTF's own cameras stay unless the manifest names some.
  if (!manifest.cameras.empty()) scene.cameras = manifest.cameras;
  // A glTF camera's path moves that camera: a manifest with cameras of its own drops it, and its own
  // camera_path replaces it.
  if (!manifest.cameras.empty() || !manifest.camera_path.keys.empty())
    scene.camera_path = manifest.camera_path;
  // Each punctual light is one light, numbered after the emitting primitives and the geometry's
  // own lights (scene.h).
  for (PunctualLight light : manifest.lights) {
    light.light = scene.num_lights++;
    scene.punctual_lights.push_back(std::move(light));
  }
  // The environment is one light more, the last (scene.h); its image is read here, confined like
  // the geometry (a bundle ships it: scene_bundle.h).
  if (manifest.environment) {
    scene.environment = manifest.environment;
    LoadEnvironmentImage(path, root, path.has_parent_path() ? path.parent_path() : std::filesystem::path("."),
                         &*scene.environment, &texels);
    scene.environment->light = scene.num_lights++;
  }
  if (scale_override > 0.0)
    ApplyScale(scale_override, SourceLocation{manifest_file, 0}, "scale override", &scene);
  else
    ApplyScale(manifest.scale, SourceLocation{manifest_file, manifest.scale_line}, "key 'scale'", &scene);
  scene.warnings.insert(scene.warnings.begin(), manifest.warnings.begin(), manifest.warnings.end());
  scene.source = manifest_file;
  return scene;
}

// A scene without any light renders black: an input error, never a black image with exit 0. Here
// because every render reads its scene through LoadScene (pf render, the coordinator's upload,
// the workers' bundles), and said once with every reason we know of.
void RequireLight(const SceneDescription& scene, const std::filesystem::path& path) {
  if (scene.num_lights > 0) return;
  const std::string ext = LowerExtension(path);
  std::string why = "the scene has no light: no material emits (MGF 'ed', OBJ/MTL 'Ke', glTF emissiveFactor)";
  why += ext == ".json" ? " and the manifest has no \"lights\" and no \"environment\""
         : ext == ".gltf" || ext == ".glb"
             ? " and the file has no KHR_lights_punctual light on a node of its scene (a manifest can add "
               "\"lights\" or an \"environment\", docs/scene-manifest.md)"
             : " and a bare geometry file has no \"lights\" (a manifest can add them or an \"environment\", "
               "docs/scene-manifest.md)";
  for (const std::string& name : scene.ambient_only_materials)
    why += "; material '" + name + "' has Ka but no Ke: Ka is not emission in pf; use Ke";
  throw InputError(SourceLocation{path.string(), 0}, why);
}

// A load frees most of what it allocated (tinyobjloader's per-face lists, the MGF loader's double
// positions), but glibc keeps freed small blocks in the process: 110 MB after a 5M-face OBJ
// (docs/security.md, "Scene budgets"). The coordinator loads every uploaded scene and a worker
// every scene it renders, so they are given back.
void ReturnFreedMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace

SceneDescription LoadScene(const std::filesystem::path& path, double scale_override,
                           const std::filesystem::path& root) {
  SceneDescription scene = LoadSceneFiles(path, scale_override, root);
  ReturnFreedMemory();
  RequireLight(scene, path);
  return scene;
}

CameraSpec DefaultCamera(const SceneDescription& scene) {
  CameraSpec cam;
  const Bounds3 b = scene.ComputeBounds();
  if (b.Empty()) return cam;
  const Vec3 c = b.Center();
  const Vec3 half = b.Diagonal() * 0.5f;
  const float tan_half = std::tan(0.5f * cam.vfov_degrees * kPi / 180.0f);
  const float aspect = float(cam.width) / float(cam.height);
  // Distance from the +z face at which its x-y extent fits the frame, with a 5 % margin.
  float d = 1.05f * std::max(half.y / tan_half, half.x / (tan_half * aspect));
  if (!(d > 0.0f)) d = std::max(1.0f, half.z);  // a flat or point-like scene
  // Computed in the scene's frame (in float, as always), then put into world coordinates.
  cam.eye = Vec3d(Vec3(c.x, c.y, b.hi.z + d)) + scene.origin;
  cam.look_at = Vec3d(c) + scene.origin;
  cam.up = Vec3(0, 1, 0);
  return cam;
}

}  // namespace pf
