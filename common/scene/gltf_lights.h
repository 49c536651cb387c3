#pragma once
// KHR_lights_punctual → pf's punctual lights (punctual_light.h; docs/gltf.md, "Lights").
//
// Units: the extension's values are photometric (point and spot intensity in candela,
// directional in lux). pf's lights are radiometric; one convention, applied to every light:
// the value is divided by 683 lm/W (the luminous efficacy of 555 nm light, the SI candela's
// definition), i.e. I [W/sr] = color · intensity / 683 and E⊥ [W/m²] = color · intensity / 683.
// Spot cone angles are radians (innerConeAngle default 0, outerConeAngle default π/4) and
// become the spot's half-angles in degrees (inner = outer, as Blender writes a spot without
// blend, is a hard-edged cone); `range` is not modelled (a warning: pf's lights
// fall off as 1/d² without a cut-off).

#include <string>
#include <vector>

#include "common/scene/mgf_transform.h"
#include "common/scene/punctual_light.h"

namespace tinygltf {
struct Light;
}

namespace pf {

// lm/W: the divisor above.
inline constexpr double kLumensPerWatt = 683.0;

// Light `index` of the file `file`, placed by its node's world transform (the light sits at the
// node's origin and shines down its −Z). Throws InputError ("scene.gltf: KHR_lights_punctual.
// lights[1]: ...") for an unknown type, a negative or overflowing intensity, or cone angles out
// of 0 ≤ inner ≤ outer ≤ π/2 (outer > 0). Returns false (with a warning) for a light that emits nothing.
bool MapGltfLight(const tinygltf::Light& light, size_t index, const mgf::Affine& world,
                  const std::string& file, std::vector<std::string>* warnings, PunctualLight* out);

}  // namespace pf
