// Textured materials at a hit (surface_material.h).
#include "common/scene/surface_material.h"

#include <algorithm>

#include "common/scene/metallic_roughness.h"

namespace pf {

MaterialTexels TexelsAt(const SceneDescription& scene, const Material& material,
                        const TextureCoordinates& uv) {
  MaterialTexels t;
  if (material.base_color_texture >= 0)
    t.base_color = scene.textures[size_t(material.base_color_texture)].Lookup(uv);
  if (material.metallic_roughness_texture >= 0)
    t.metallic_roughness = scene.textures[size_t(material.metallic_roughness_texture)].Lookup(uv);
  if (material.transmission_texture >= 0)
    t.transmission = scene.textures[size_t(material.transmission_texture)].Lookup(uv).r;
  if (material.emission_texture >= 0)
    t.emission = scene.textures[size_t(material.emission_texture)].Lookup(uv);
  return t;
}

void ApplyTexels(const Material& material, const MaterialTexels& texels, Material* out) {
  *out = material;
  if (material.emission_texture >= 0) out->emission = material.emission * texels.emission;
  if (material.base_color_texture < 0 && material.metallic_roughness_texture < 0 &&
      material.transmission_texture < 0)
    return;
  if (material.metallic_roughness) {
    // glTF: baseColor = factor × texel, metallic = factor × B, roughness = factor × G
    // (specification §3.9.2), mapped exactly as the loader maps the factors
    // (metallic_roughness.h), so the texture keeps the mapping's energy bound. With factors and
    // white texels the numbers are the untextured material's bit for bit (× 1 is exact).
    MetallicRoughness p = *material.metallic_roughness;
    p.base_color = p.base_color * texels.base_color;
    if (material.metallic_roughness_texture >= 0) {
      p.metallic = p.metallic * texels.metallic_roughness.b;
      p.roughness = p.roughness * texels.metallic_roughness.g;
    }
    if (material.transmission_texture >= 0) p.transmission = p.transmission * texels.transmission;
    const Material mapped = MetallicRoughnessMaterial(p);
    out->diffuse_reflectance = mapped.diffuse_reflectance;
    out->specular_reflectance = mapped.specular_reflectance;
    out->specular_transmittance = mapped.specular_transmittance;
    out->microfacet_f90 = mapped.microfacet_f90;
    if (material.metallic_roughness_texture >= 0 || material.transmission_texture >= 0) {
      // Metallic and transmission decide the lobes too (a transmissive material is a dielectric
      // below metallic 1).
      out->microfacet = mapped.microfacet;
      out->microfacet_roughness = mapped.microfacet_roughness;
      out->ior = mapped.microfacet == Material::Microfacet::kDielectric ? mapped.ior : material.ior;
    }
    return;
  }
  // OBJ map_Kd: the texture multiplies Kd (the MTL convention). A texel above 1 (an HDR or EXR
  // texture) could make ρd + ρs exceed 1: each channel is capped at what energy allows.
  Rgb kd = material.diffuse_reflectance * texels.base_color;
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
  ApplyTexels(material, TexelsAt(scene, material, uv), &**scratch);
  return **scratch;
}

float AlphaAt(const SceneDescription& scene, const Material& material, const TextureCoordinates& uv) {
  if (material.alpha_texture < 0) return material.alpha_factor;
  return material.alpha_factor * scene.textures[size_t(material.alpha_texture)].LookupAlpha(uv);
}

}  // namespace pf
