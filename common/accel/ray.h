#pragma once
// Rays, hits and the robust ray-origin offset. No Embree here: accel/embree_scene.cpp is the
// only file that includes Embree (docs/design.md, S3: one place per third-party library).

#include <cstdint>
#include <limits>

#include "common/core/math.h"

namespace pf {

struct Ray {
  Vec3 origin;
  Vec3 direction;  // unit length
  float t_max = std::numeric_limits<float>::infinity();
};

// A surface hit, already resolved against the scene description.
struct SurfaceHit {
  float t = 0.0f;
  uint32_t triangle = 0;
  Vec3 position;          // interpolated from the vertices (more accurate than o + t·d)
  Vec3 geometric_normal;  // unit normal of the triangle's front face (vertex order, right hand)
  Vec3 shading_normal;    // unit, interpolated vertex normal (or geometric), same side as ng
  uint32_t material = 0;
  uint32_t light = 0xffffffffu;  // kNoLight unless the triangle emits
  bool front_face = true;        // the ray arrived on the front side
};

// Moves a surface point off the surface along `normal` (unit, pointing to the side the next ray
// leaves from) by an amount that covers the floating-point error of the intersection.
// Intersection error is relative to the magnitude of the coordinates involved, so the offset is
// too: ~2^-15 of the largest coordinate (plus a floor from the scene's own size, which covers
// points near the origin of a large scene). This keeps scenes from 1e-3 m to 1e4 m free of acne
// and of light leaks through closed surfaces (tests: furnace at three scales).
// RayOffset is that amount at p.
inline float RayOffset(const Vec3& p, float scene_epsilon) {
  const float magnitude = MaxComponent(Vec3(std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)));
  return std::max(magnitude * 0x1p-15f, scene_epsilon);
}
inline Vec3 OffsetRayOrigin(const Vec3& p, const Vec3& normal, float scene_epsilon) {
  return p + normal * RayOffset(p, scene_epsilon);
}

}  // namespace pf
