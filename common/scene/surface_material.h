#pragma once
// The material at a surface point: the scene's material, with its texture applied for a textured
// one (docs/renderer.md, "Textures"). Every place that builds a BSDF at a hit (camera paths, the
// photon walk of Wald 1999 §2.2, the local pass, importance and Metropolis chains) takes its
// material from here, so a photon carries the textured albedo at every bounce and an estimate
// reads the albedo at its query point.

#include <cstdint>
#include <optional>

#include "common/scene/scene.h"

namespace pf {

// The texels a material's textures give at a hit: white (1) for a slot without a texture.
struct MaterialTexels {
  Rgb base_color{1.0f};          // base_color_texture's colour
  Rgb metallic_roughness{1.0f};  // metallic_roughness_texture's (G: roughness, B: metallic)
  float transmission = 1.0f;     // transmission_texture's red channel
  Rgb emission{1.0f};            // emission_texture's
};

// The texels of `material`'s textures at texture coordinates `uv`.
MaterialTexels TexelsAt(const SceneDescription& scene, const Material& material,
                        const TextureCoordinates& uv);

// `material` with `texels` applied (scene.h, Material::base_color_texture, metallic_roughness_texture
// and transmission_texture): a material mapped from glTF's metallic-roughness parameters is
// mapped again from baseColorFactor × base texel, metallicFactor × B, roughnessFactor × G and
// transmissionFactor × R;
// an OBJ material has ρd multiplied by the base texel; the emission is multiplied by its texel.
// Not textured: the material itself.
// Copies into *out, which must not be `material`.
void ApplyTexels(const Material& material, const MaterialTexels& texels, Material* out);

// The material of scene material `index` at texture coordinates `uv`: a reference to
// scene.materials[index] when it has no texture (no copy, and *scratch stays empty: the common
// case costs the test alone), otherwise **scratch, filled by ApplyTexels with its textures'
// texels at uv. The reference lives as long as both the scene and *scratch.
const Material& MaterialAt(const SceneDescription& scene, uint32_t index, const TextureCoordinates& uv,
                           std::optional<Material>* scratch);

// The alpha of a masked material at `uv` (scene.h, Material::alpha_cutoff), and whether the
// surface is cut out there: alpha < cutoff.
float AlphaAt(const SceneDescription& scene, const Material& material, const TextureCoordinates& uv);
inline bool IsCutOut(const SceneDescription& scene, const Material& material, const TextureCoordinates& uv) {
  return AlphaAt(scene, material, uv) < material.alpha_cutoff;
}

}  // namespace pf
