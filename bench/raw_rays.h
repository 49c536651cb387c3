#pragma once
// The "raw incoherent Embree ray" workload that embree_bench's "second." column and
// photon_tracing_bench's ratio both measure: one ray per camera-ray hit of a res × res image, in a
// cosine-distributed direction about the hit's normal (facing the camera), from the offset hit
// point. Fixed rays (seeded), so every measurement traces the same set.

#include <cmath>
#include <cstddef>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/core/rng.h"

namespace pf::bench {

inline std::vector<Ray> IncoherentSecondaryRays(const EmbreeScene& accel, const Camera& camera, int res,
                                                Rng& rng) {
  std::vector<Ray> rays;
  for (int y = 0; y < res; ++y)
    for (int x = 0; x < res; ++x) {
      const Ray cr = camera.GenerateRay(x, y, rng.Uniform(), rng.Uniform());
      const auto hit = accel.Intersect(cr);
      if (!hit) continue;
      Vec3 n = hit->geometric_normal;
      if (Dot(n, cr.direction) > 0) n = -n;
      const float u1 = rng.Uniform(), u2 = rng.Uniform();
      const float rr = std::sqrt(u1), phi = kTwoPi * u2;
      const Vec3 d = Frame(n).ToWorld(Vec3(rr * std::cos(phi), rr * std::sin(phi), std::sqrt(1 - u1)));
      rays.push_back(Ray{accel.SpawnOrigin(*hit, d), d});
    }
  return rays;
}

// Closest-hit queries through EmbreeScene::Intersect (Embree plus the hit's bookkeeping, as every
// renderer ray pays), `passes` times over `rays`; the number of hits, so the loop is not elided.
inline size_t IntersectAll(const EmbreeScene& accel, const std::vector<Ray>& rays, int passes = 1) {
  size_t hits = 0;
  for (int p = 0; p < passes; ++p)
    for (const Ray& ray : rays) hits += accel.Intersect(ray).has_value();
  return hits;
}

}  // namespace pf::bench
