#pragma once
// glTF 2.0 materials → pf's Material (scene.h): the one place that says how (docs/gltf.md,
// "Materials"). Provisional: pf's BSDF is Ward's (diffuse + specular/Ward reflection,
// specular transmission), not glTF's GGX metallic-roughness model (glTF 2.0 spec, Appendix B),
// so the mapping keeps the factors' energy split and approximates the lobe shapes:
//   diffuse_reflectance     = baseColor · (1 − metallic) · (1 − transmission)
//   specular_reflectance    = baseColor · metallic, Ward α = roughness² (a mirror below 1e-3)
//   specular_transmittance  = baseColor · (1 − metallic) · transmission, ior = KHR_materials_ior
//                             (1.5 by default): a smooth glass (KHR_materials_transmission)
//   emission                = emissiveFactor · KHR_materials_emissive_strength, taken as
//                             radiance Le in W/(m²·sr) (as Blender's exporter writes Cycles'
//                             emission strength)
//   one_sided               = !doubleSided (recorded; pf shades both sides)
// Factors are clamped to [0, 1] as the spec bounds them; the dielectric's ~4 % specular layer
// (F0 = 0.04) is not modelled. Textures (any slot) and alpha modes other than OPAQUE are not
// applied: one warning per material names them, never silently.

#include <string>
#include <vector>

#include "common/scene/scene.h"

namespace tinygltf {
struct Material;
}

namespace pf {

// Maps material `index` of the file `file` (messages: "scene.gltf: materials[2] 'Wood': ...").
// Appends its warnings; throws InputError for an emission that is not a finite float.
Material MapGltfMaterial(const tinygltf::Material& material, size_t index, const std::string& file,
                         std::vector<std::string>* warnings);

// The material of primitives without one (glTF 2.0 spec, §3.9.1: the default material is a
// rough, non-metallic white; pf uses the same).
Material DefaultGltfMaterial();

}  // namespace pf
