#pragma once
// The floor of a photon walk's own cost (issue #18: "photon tracing at >= 60 % of the raw
// incoherent Embree ray rate"): the least a photon random walk (Wald 1999, §2.2) can do per ray
// and still be one — a point on an emitter and a cosine-distributed first direction, then at
// every hit EmbreeScene::IntersectWalk (position, normal, material: what any walk needs), the
// photon's 56-byte record appended, Russian roulette on the material's diffuse albedo (specular
// materials absorb: compare it on diffuse scenes such as Cornell and office3), a new
// cosine direction about the facing normal and an offset origin. Its numbers come from one PCG32
// stream (Rng) instead of the tracer's Owen-scrambled Sobol lanes, and it has no Bsdf lobes,
// caustic flag, light stratification or importance test. It is not a photon tracer (its map is
// not the tracer's): it measures how close to the raw ray rate any scalar, one-ray-at-a-time
// walk built from the same parts can come, so the tracer's ratio can be read against it.

#include <cstdint>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/accel/ray.h"
#include "common/core/math.h"
#include "common/core/rng.h"
#include "common/photon/photon_tracer.h"
#include "common/render/light_sampler.h"

namespace pf::bench {

struct FloorWalkResult {
  uint64_t rays = 0;
  TracedPhotons photons;
};

inline FloorWalkResult FloorWalk(const EmbreeScene& scene, const LightSampler& lights, uint64_t photons,
                                 uint64_t seed) {
  struct Emitter {
    Vec3 a, b, c, normal;
    Frame frame;
  };
  const SceneDescription& desc = scene.description();
  std::vector<Emitter> emitters;
  for (size_t i = 0; i < lights.num_emitting_triangles(); ++i) {
    const LightSample ls = lights.EmitterSample(i, 0.0f, 0.0f);
    const auto& t = desc.triangles[ls.triangle];
    emitters.push_back(
        {desc.positions[t[0]], desc.positions[t[1]], desc.positions[t[2]], ls.normal, Frame(ls.normal)});
  }
  // P(survive) = the channel mean of ρd, as the tracer's roulette on a diffuse surface (§2.2,
  // BsdfLobes), so both walks trace about as many rays per photon; weight ρd / P.
  std::vector<float> survive;
  std::vector<Rgb> weight;
  for (const Material& m : desc.materials) {
    const Rgb& rho = m.diffuse_reflectance;
    const float p = (rho.r + rho.g + rho.b) / 3.0f;
    survive.push_back(p);
    weight.push_back(p > 0.0f ? rho * (1.0f / p) : Rgb(0.0f));
  }
  FloorWalkResult result;
  result.photons.reserve(photons * 2);
  Rng rng(seed, 7);
  const Rgb power(1.0f / float(photons));
  const float epsilon = scene.epsilon();
  WalkHit hit;
  for (uint64_t i = 0; i < photons; ++i) {
    const Emitter& em = emitters[lights.EmitterIndex(rng.Uniform())];
    const float u1 = rng.Uniform(), u2 = rng.Uniform(), u3 = rng.Uniform(), u4 = rng.Uniform();
    Vec3 previous = SampleTriangle(em.a, em.b, em.c, u1, u2);
    Ray ray{OffsetRayOrigin(previous, em.normal, epsilon), em.frame.ToWorld(CosineHemisphereFast(u3, u4))};
    Rgb phi = power;
    for (int bounce = 0; bounce < 8; ++bounce) {
      ++result.rays;
      if (!scene.IntersectWalk(ray, &hit)) break;
      const Vec3 wo = -ray.direction;
      result.photons.push_back({hit.position, wo, phi, previous, 0, PhotonKind::kIndirect});
      const float u_rr = rng.Uniform(), v1 = rng.Uniform(), v2 = rng.Uniform();
      if (!(u_rr < survive[hit.material])) break;
      phi *= weight[hit.material];
      const Vec3 n = Dot(wo, hit.geometric_normal) >= 0.0f ? hit.geometric_normal : -hit.geometric_normal;
      previous = hit.position;
      ray = Ray{OffsetRayOrigin(hit.position, n, epsilon), Frame(n).ToWorld(CosineHemisphereFast(v1, v2))};
    }
  }
  return result;
}

}  // namespace pf::bench
