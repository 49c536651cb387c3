// Textured materials at a hit (surface_material.h).
#include "common/scene/surface_material.h"

#include <algorithm>

#include "common/scene/metallic_roughness.h"

namespace pf {

void ApplyTexel(const Material& material, const Rgb& texel, Material* out) {
  *out = material;
  if (!IsTextured(material)) return;
  if (material.metallic_roughness) {
    // glTF: baseColor = factor × texel (specification §3.9.2), mapped exactly as the loader maps
    // the factor (metallic_roughness.h), so the texture keeps the mapping's energy bound.
    MetallicRoughness p = *material.metallic_roughness;
    p.base_color = p.base_color * texel;
    const Material mapped = MetallicRoughnessMaterial(p);
    out->diffuse_reflectance = mapped.diffuse_reflectance;
    out->specular_reflectance = mapped.specular_reflectance;
    out->specular_transmittance = mapped.specular_transmittance;
    out->microfacet_f90 = mapped.microfacet_f90;
    return;
  }
  // OBJ map_Kd: the texture multiplies Kd (the MTL convention). A texel above 1 (an HDR or EXR
  // texture) could make ρd + ρs exceed 1: each channel is capped at what energy allows.
  Rgb kd = material.diffuse_reflectance * texel;
  for (int c = 0; c < 3; ++c) {
    const float room = 1.0f - material.specular_reflectance[c] - material.diffuse_transmittance[c] -
                       material.specular_transmittance[c];
    kd[c] = std::min(kd[c], std::max(room, 0.0f));
  }
  out->diffuse_reflectance = kd;
}

const Material& MaterialAt(const SceneDescription& scene, uint32_t index, const TextureCoordinates& uv,
                           std::optional<Material>* scratch) {
  const Material& material = scene.materials[index];
  if (!IsTextured(material)) return material;
  if (!*scratch) scratch->emplace();
  ApplyTexel(material, scene.textures[size_t(material.base_color_texture)].Lookup(uv), &**scratch);
  return **scratch;
}

}  // namespace pf
