#pragma once
// glTF 2.0 materials → pf's Material (scene.h): the one place that says how (docs/gltf.md,
// "Materials"). pbrMetallicRoughness with KHR_materials_transmission and KHR_materials_ior goes
// through MetallicRoughnessMaterial (metallic_roughness.h): GGX conductor lobe over a Lambertian
// one, or a GGX dielectric for transmission (glTF 2.0 spec, Appendix B); then
//   emission   = emissiveFactor · KHR_materials_emissive_strength, taken as radiance Le in
//                W/(m²·sr) (as Blender's exporter writes Cycles' emission strength)
//   one_sided  = !doubleSided (recorded; pf shades both sides)
// Factors are clamped to [0, 1] as the spec bounds them. Textures (any slot) and alpha modes
// other than OPAQUE are not applied: one warning per material names them, never silently.

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
