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

// `material` with `texel` applied to its base colour (scene.h, Material::base_color_texture).
// Not textured: the material itself. Copies into *out, which must not be `material`.
void ApplyTexel(const Material& material, const Rgb& texel, Material* out);

// The material of scene material `index` at texture coordinates `uv`: a reference to
// scene.materials[index] when it has no texture (no copy, and *scratch stays empty: the common
// case costs the test alone), otherwise **scratch, filled by ApplyTexel with the texture's
// colour at uv. The reference lives as long as both the scene and *scratch.
const Material& MaterialAt(const SceneDescription& scene, uint32_t index, const TextureCoordinates& uv,
                           std::optional<Material>* scratch);

inline bool IsTextured(const Material& material) {
  return material.base_color_texture >= 0;
}

}  // namespace pf
