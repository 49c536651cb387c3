#pragma once
// glTF 2.0's metallic-roughness parameters of one material (specification §3.9.2), apart from
// their mapping onto a Material (metallic_roughness.h): a Material keeps the parameters it was
// mapped from, so that a base-colour texture can be applied at each hit by mapping them again
// (scene/surface_material.h).

#include "common/core/math.h"

namespace pf {

// The glTF parameters of one material (defaults: the specification's).
struct MetallicRoughness {
  Rgb base_color{1.0f};       // baseColorFactor (× texture), linear
  float metallic = 1.0f;      // metallicFactor, [0, 1]
  float roughness = 1.0f;     // roughnessFactor, [0, 1]; GGX α = roughness²
  float transmission = 0.0f;  // KHR_materials_transmission, [0, 1]
  float ior = 1.5f;           // KHR_materials_ior (> 0; 0 in the extension means 1.5 here)
};

// glTF's dielectric specular reflectance at normal incidence, ((ior − 1)/(ior + 1))² at 1.5.
inline constexpr float kGltfDielectricF0 = 0.04f;

}  // namespace pf
