#pragma once
// The floor of a photon walk's own cost (docs/results/kernel.md: "photon tracing at >= 60 % of the raw
// incoherent Embree ray rate"): about the least a photon random walk (Wald 1999, §2.2) can do per
// ray and still be one — a point on an emitter and a cosine-distributed first direction (the
// tracer's PhotonEmitters table), then at every hit EmbreeScene::IntersectWalk (position, normal,
// material: what any walk needs), the photon appended where the material stores photons (the
// tracer's AppendPhoton), Russian roulette with the tracer's own survival probability (the
// material's roulette lobes, WalkRoulette), a new cosine direction about the facing normal and an
// offset origin, up to the tracer's bounce cap. Its numbers come from one PCG32 stream (Rng)
// instead of the tracer's Owen-scrambled Sobol lanes, and it has no light stratification, no lobe
// choice or Bsdf (a surviving photon leaves every surface — glass and mirrors too — diffusely), no
// caustic flag, no importance test. So it traces about as many rays per photon and stores about as
// many photons as the tracer (the bench prints both) with none of the tracer's bookkeeping. It is
// not a photon tracer (its map is not the tracer's): it measures how close to the raw ray rate a
// scalar, one-ray-at-a-time walk built from the same parts comes, so that the tracer's ratio can
// be read against it.

#include <cstdint>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/accel/ray.h"
#include "common/core/math.h"
#include "common/core/rng.h"
#include "common/lights/light_sampler.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_tracer.h"

namespace pf::bench {

struct FloorWalkResult {
  uint64_t rays = 0;
  TracedPhotons photons;
};

inline FloorWalkResult FloorWalk(const EmbreeScene& scene, const LightSampler& lights, uint64_t photons,
                                 uint64_t seed) {
  FloorWalkResult result;
  if (lights.empty() || photons == 0) return result;
  const SceneDescription& desc = scene.description();
  // The tracer's own emitter table and photon append (photon_tracer.h).
  const std::vector<PhotonEmitter> emitters = PhotonEmitters(desc, lights, photons);
  // Per material, the tracer's roulette (WalkRoulette::Of): P(survive) = the sum of its lobes'
  // roulette probabilities, stored where it has a diffuse lobe; the weight ρd / P(diffuse).
  struct Surface {
    float survive = 0.0f;
    bool stores = false;
    Rgb weight;
  };
  std::vector<Surface> surfaces;
  for (const Material& m : desc.materials) {
    const WalkRoulette w = WalkRoulette::Of(m, BsdfLobes::Of(m));
    surfaces.push_back({w.absorb_from, w.has_diffuse, w.p_diffuse > 0.0f ? w.diffuse_weight : Rgb(1.0f)});
  }
  const int max_bounces = PhotonTracerOptions().max_bounces;
  result.photons.reserve(photons * 2);
  Rng rng(seed, 7);
  const float epsilon = scene.epsilon();
  WalkHit hit;
  for (uint64_t i = 0; i < photons; ++i) {
    const PhotonEmitter& em = emitters[lights.EmitterIndex(rng.Uniform())];
    const float u1 = rng.Uniform(), u2 = rng.Uniform(), u3 = rng.Uniform(), u4 = rng.Uniform();
    Vec3 previous = SampleTriangle(em.a, em.b, em.c, u1, u2);
    Ray ray{OffsetRayOrigin(previous, em.normal, epsilon), em.frame.ToWorld(CosineHemisphereFast(u3, u4))};
    Rgb phi = em.power;
    for (int bounce = 0; bounce < max_bounces; ++bounce) {
      ++result.rays;
      if (!scene.IntersectWalk(ray, &hit)) break;
      const Surface& surface = surfaces[hit.material];
      const Vec3 wo = -ray.direction;
      if (surface.stores)
        AppendPhoton(result.photons, hit.position, wo, phi, previous, em.light,
                     bounce == 0 ? PhotonKind::kDirect : PhotonKind::kIndirect);
      const float u_rr = rng.Uniform(), v1 = rng.Uniform(), v2 = rng.Uniform();
      if (!(u_rr < surface.survive)) break;
      phi *= surface.weight;
      const Vec3 n = Dot(wo, hit.geometric_normal) >= 0.0f ? hit.geometric_normal : -hit.geometric_normal;
      previous = hit.position;
      ray = Ray{OffsetRayOrigin(hit.position, n, epsilon), Frame(n).ToWorld(CosineHemisphereFast(v1, v2))};
    }
  }
  return result;
}

}  // namespace pf::bench
