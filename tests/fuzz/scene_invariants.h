#pragma once
// The output contract the scene-loader fuzz targets check on every scene a loader returns:
// every vertex index, material and light id in range, one material and one light id per
// triangle, no or one normal per position, finite positions. A violation traps (a libFuzzer
// finding).

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "common/scene/scene.h"

namespace pf::fuzz {

inline void TrapUnlessWellFormed(const SceneDescription& scene) {
  if (scene.triangle_material.size() != scene.triangles.size() ||
      scene.triangle_light.size() != scene.triangles.size() ||
      (!scene.normals.empty() && scene.normals.size() != scene.positions.size()))
    __builtin_trap();
  for (size_t t = 0; t < scene.triangles.size(); ++t) {
    for (uint32_t v : scene.triangles[t])
      if (v >= scene.positions.size()) __builtin_trap();
    if (scene.triangle_material[t] >= scene.materials.size()) __builtin_trap();
    const uint32_t light = scene.triangle_light[t];
    if (light != kNoLight && light >= scene.num_lights) __builtin_trap();
  }
  for (const Vec3& p : scene.positions)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) __builtin_trap();
}

}  // namespace pf::fuzz
