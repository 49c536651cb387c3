// glTF metallic-roughness → Material (metallic_roughness.h). The glTF BRDF blends a dielectric
// (diffuse under a specular layer, fresnel_mix with F0 = 0.04) and a metal (specular tinted by
// baseColor) by `metallic`. Bsdf has one GGX reflection lobe per material and a Lambertian
// lobe beside it, so the blend is the usual single-lobe form: Schlick's F0 interpolated between
// 0.04 and baseColor, the diffuse lobe weighted by (1 − metallic) and by (1 − F0) at normal
// incidence. The diffuse lobe cannot give up energy per angle as glTF's layer does, so Schlick's
// rise towards 1 at grazing angles is capped at F90 = max(metallic, max F0): then
// ρd + F ≤ (1 − metallic)·0.96 + 0.04·(1 − metallic) + metallic = 1 in every channel and at
// every angle (tests/common/metallic_roughness_test.cpp). A metal keeps F90 = 1; a non-metal
// keeps its 4 % at grazing angles (it loses glTF's Fresnel sheen there).

#include "common/scene/metallic_roughness.h"

#include <algorithm>
#include <cmath>

namespace pf {
namespace {

float Clamp01(float v, float fallback) {
  return std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : fallback;
}

}  // namespace

Material MetallicRoughnessMaterial(const MetallicRoughness& p) {
  Rgb base;
  for (int c = 0; c < 3; ++c) base[c] = Clamp01(p.base_color[c], 1.0f);
  const float metallic = Clamp01(p.metallic, 1.0f);
  const float roughness = Clamp01(p.roughness, 1.0f);
  const float transmission = Clamp01(p.transmission, 0.0f);
  Material m;
  m.microfacet_roughness = roughness;
  if (transmission > 0.0f && metallic < 1.0f) {
    m.microfacet = Material::Microfacet::kDielectric;
    m.specular_transmittance = base;
    m.ior = std::isfinite(p.ior) && p.ior > 0.0f ? p.ior : 1.5f;
    return m;
  }
  m.microfacet = Material::Microfacet::kConductor;
  m.specular_reflectance = Rgb(kGltfDielectricF0 * (1.0f - metallic)) + base * metallic;
  m.diffuse_reflectance = base * ((1.0f - metallic) * (1.0f - kGltfDielectricF0));
  // ρd + F ≤ 1 at every angle in every channel (metallic_roughness.h).
  m.microfacet_f90 = std::max(metallic, m.specular_reflectance.Max());
  return m;
}

}  // namespace pf
