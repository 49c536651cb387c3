#pragma once
// glTF 2.0's metallic-roughness material (specification §3.9.2 and Appendix B) mapped onto a
// Material with GGX lobes (materials/bsdf_microfacet.h), for scene loaders (glTF) to call.
// docs/renderer.md, "Microfacet lobes", documents the mapping and what it approximates.

#include "common/scene/metallic_roughness_params.h"
#include "common/scene/scene.h"

namespace pf {

// The Material (GGX conductor lobe + Lambertian lobe, or a GGX dielectric):
//   F0 (ρs, Schlick) = 0.04·(1 − metallic) + base_color·metallic
//   ρd = base_color·(1 − metallic)·(1 − 0.04)
//   F90 (Schlick's grazing reflectance) = max(metallic, max channel of F0): energy ≤ 1 always
//   microfacet = kConductor, microfacet_roughness = roughness.
// With transmission > 0 and metallic < 1: a GGX dielectric (kDielectric) with τs = base_color
// and the ior; its reflection is Fresnel's. Inputs are clamped to their ranges (NaN → default).
Material MetallicRoughnessMaterial(const MetallicRoughness& p);

}  // namespace pf
