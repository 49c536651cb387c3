#pragma once
// Separate direct illumination (Wald 1999, §4.2): Lr = Ld (direct) + Li (soft indirect, from
// the global map *without* the direct photons) + Lc (caustics). Two estimators of Ld:
//
// * Monte Carlo (§4.2.1): N shadow rays per shading point, stratified over the lights with
//   selection probability ∝ power — sample j takes the j-th stratum of [0,1) through the
//   lights' power CDF, so light i gets N·p_i ± 1 rays — then a point ∝ power within the light.
//   Option beyond the thesis: `uniform_fraction` β mixes a uniform choice into the light
//   probabilities, p_i = (1−β)·Φ_i/ΣΦ + β/L (light_choice.h: a dim but close light is never
//   starved). The estimate Σ_j f·Le·V·G / (N·p_i·p(y|i)) is unbiased for any β < 1.
//
// * PhotonDirect (§4.2.3): query the direct photons (tagged with their light) at x; E_i = power
//   of the found photons from light i. Contributing lights (E_i > 0) get
//   N_i = max(1, round(N·E_i/ΣE)) samples; the others ("non-contributing", possibly
//   occluded) get either one sample to one of them chosen uniformly, weighted by their count
//   (kOneRandom), or one sample each with weight 1 (kEachOne, the thesis's footnote). Every
//   light keeps a non-zero probability of being sampled, so the estimate stays unbiased.
//   Neighbour-set cache: the last query's contributing set and sample counts are reused while
//   x stays within `cache_radius_fraction`·r of the cached point and the normals agree
//   (cos > 0.9) — the thesis found ×20 on SCENE10 from scanline coherence. Here the cache
//   lives only within the samples of one pixel (t_pixel_epoch), because reusing it across
//   pixels would make the image depend on which pixels a thread rendered before.
//
// Punctual lights (point, spot, directional; light_sampler.h) are lights like the others here:
// each its own light id, power and photons; their one "sample" is the light itself. So is the
// environment (environment_light.h): its samples are directions, importance-sampled by its
// luminance, and its photons are tagged with its light id.

#include <cstdint>
#include <limits>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/core/rng.h"
#include "common/estimators/trace_counters.h"
#include "common/lights/light_choice.h"
#include "common/lights/light_sampler.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_map.h"
#include "common/sampling/sample_layout.h"

namespace pf {

struct DirectLightOptions {
  int shadow_rays = 16;           // N per shading point (MC), N_total (PhotonDirect)
  float uniform_fraction = 0.0f;  // β (MC)
};

class MonteCarloDirectLight {
 public:
  MonteCarloDirectLight(const EmbreeScene& scene, const LightSampler& lights, DirectLightOptions options);
  // Ray j of the N draws its numbers from `slots` at sub-index j (sample_layout.h).
  Rgb Estimate(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes, Sampler& sampler,
               const PathVertexSlots& slots, TraceCounters& counters) const;

 private:
  const EmbreeScene& scene_;
  const LightSampler& lights_;
  DirectLightOptions options_;
  LightChoice choice_;
};

// One light sample's contribution f·Le·V·cos·cos/d² / pdf_area (pdf within the light), or 0:
// u_select picks the triangle within the light, `u` the point on it. Only the BSDF lobes in
// `lobes` are evaluated (lobes followed by recursion see the emitters themselves).
Rgb SampleOneLight(const EmbreeScene& scene, const LightSampler& lights, size_t light, const Bsdf& bsdf,
                   const Vec3& x, const Vec3& wo, uint32_t lobes, float u_select, Sample2 u,
                   TraceCounters& counters);

// A delta light's sample (point, spot, directional; ls.delta()): f·E·|cos θ|·V / p, with E the
// irradiance it sends to x (LightSampler::Incidence) and p = ls.pdf_area the probability of its
// choice. No MIS: no BSDF sample can hit a delta light (Veach 1997, §9.2.3).
Rgb DeltaLightContribution(const LightSampler& lights, const LightSample& ls, const Bsdf& bsdf, const Vec3& x,
                           const Vec3& wo, uint32_t lobes, TraceCounters& counters);

// An environment sample (ls.environment): f·L·|cos θ|·V / p with p = ls.pdf_area·ls.pdf_direction
// its density per solid angle; 0 where p is 0. Unweighted: a caller with MIS weighs it.
Rgb EnvironmentLightContribution(const LightSampler& lights, const LightSample& ls, const Bsdf& bsdf,
                                 const Vec3& x, const Vec3& wo, uint32_t lobes, TraceCounters& counters);

enum class NonContributingMode { kOneRandom, kEachOne };

struct PhotonDirectOptions {
  int k = 50;        // direct photons per query
  int samples = 10;  // N_total for the contributing lights
  NonContributingMode non_contributing = NonContributingMode::kOneRandom;
  float cache_radius_fraction = 0.25f;  // 0 = no neighbour-set cache
  // Search radius bound. Where no direct photon arrives on the point's side (a ceiling lit by
  // downward lights, the back of a wall) an unbounded query would visit the whole map; with the
  // bound, such points find none and every light is treated as non-contributing (still unbiased).
  float max_radius = std::numeric_limits<float>::infinity();
};

class PhotonDirectLight {
 public:
  // `light_of_photon`: scene light id of each photon of `direct_map` (post-build order).
  PhotonDirectLight(const EmbreeScene& scene, const LightSampler& lights, const PhotonMap& direct_map,
                    const std::vector<uint32_t>& light_of_photon, PhotonDirectOptions options);
  // Shadow ray j (counted over the contributing lights, j < N_total) draws from `slots` at
  // sub-index j; the non-contributing lights' sample from light_extra (sample_layout.h).
  Rgb Estimate(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes, Sampler& sampler,
               const PathVertexSlots& slots, TraceCounters& counters, NearestPhotons& nearest) const;

  struct CacheStats {
    uint64_t queries = 0, hits = 0;
  };

 private:
  const EmbreeScene& scene_;
  const LightSampler& lights_;
  const PhotonMap& map_;
  const std::vector<uint32_t>& light_of_photon_;
  PhotonDirectOptions options_;
};

}  // namespace pf
