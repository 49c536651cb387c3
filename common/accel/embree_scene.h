#pragma once
// The runtime geometry: an Embree 3 scene built once from a SceneDescription, then traced
// read-only from many threads (Embree: commit once, trace concurrently).

#include <memory>
#include <optional>
#include <vector>

#include "common/accel/ray.h"
#include "common/scene/scene.h"

struct RTCFilterFunctionNArguments;  // embree3/rtcore_geometry.h

namespace pf {

class EmbreeScene {
 public:
  // Builds and commits the BVH. Throws SystemError if Embree reports an error.
  explicit EmbreeScene(const SceneDescription& scene);
  ~EmbreeScene();
  EmbreeScene(const EmbreeScene&) = delete;
  EmbreeScene& operator=(const EmbreeScene&) = delete;

  // Every query below skips a surface point an alpha mask cuts out (scene.h,
  // Material::alpha_cutoff; docs/renderer.md, "Alpha masks"): camera and gather rays, shadow and
  // visibility rays and photon walks alike, by an Embree filter on scenes with a mask (none
  // without, so an unmasked scene traces as before).
  //
  // Closest hit along the ray in (0, t_max], or nullopt.
  std::optional<SurfaceHit> Intersect(const Ray& ray) const;
  // The same closest hit for a particle walk: false for a miss, else *hit holds Intersect's
  // position, normals and material (WalkHit). The photon tracer's rays take this one.
  bool IntersectWalk(const Ray& ray, WalkHit* hit) const;
  // True if anything blocks the ray in (0, t_max).
  bool Occluded(const Ray& ray) const;
  // Visibility between two surface points, each offset along its normal towards the other.
  bool Visible(const Vec3& from, const Vec3& from_normal, const Vec3& to, const Vec3& to_normal) const;

  const SceneDescription& description() const { return *scene_; }
  float epsilon() const { return epsilon_; }  // absolute offset floor for ray origins
  const Bounds3& bounds() const { return bounds_; }
  const Vec3& triangle_normal(uint32_t tri) const { return face_normals_[tri]; }
  float triangle_area(uint32_t tri) const { return face_areas_[tri]; }

  // Offsets a hit point to the side of `direction` (the side the next ray leaves to).
  Vec3 SpawnOrigin(const SurfaceHit& hit, const Vec3& direction) const {
    const Vec3& n = hit.geometric_normal;
    return OffsetRayOrigin(hit.position, Dot(direction, n) >= 0 ? n : -n, epsilon_);
  }

 private:
  struct EmbreeHandles;
  // The triangle's vertex normals at barycentrics (u, v), on ng's side; false (and *n untouched)
  // when one is zero or the interpolation is degenerate. Only for a scene with vertex normals
  // (the callers test that, so a scene without them makes no call per ray).
  bool InterpolatedNormal(uint32_t triangle, float u, float v, const Vec3& ng, Vec3* n) const;
  // Embree's intersection and occlusion filter for scenes with an alpha mask: rejects a hit
  // whose material is masked and cut out at the hit's texture coordinates.
  static void CutOutFilter(const RTCFilterFunctionNArguments* args);
  const SceneDescription* scene_;
  std::unique_ptr<EmbreeHandles> embree_;
  std::vector<Vec3> face_normals_;
  std::vector<float> face_areas_;
  Bounds3 bounds_;
  float epsilon_ = 0.0f;
};

}  // namespace pf
