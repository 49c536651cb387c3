#pragma once
// Which light a light sample goes to (next-event estimation in the path tracer, the Monte Carlo
// direct light of Wald 1999, §4.2.1): light i of the LightSampler's numbering with probability
//   p_i = (1 − β)·Φ_i/ΣΦ + β/L,
// Φ_i the light's power (luminance), L the number of lights, then a point on it as
// LightSampler::SampleLight gives one (a triangle ∝ power within the light, the punctual light
// itself, a direction of the environment). β = 0 is the thesis's choice ∝ power. β > 0 is
// defensive sampling (Hesterberg 1995): power says how much light a source sends into the scene,
// not how much reaches a given point, so a spot lamp of 7 W that lights the floor under it as
// brightly as a sky of 600 W (the sky's power counts every ray through the scene's bounding disc)
// gets 1 % of the samples by power and its pool is noise (docs/results/blender-cycles.md); with
// β no light gets less than β/L of the samples, and with β = 1/2 none gets less than half of what
// either rule alone would give it, so the estimate's second moment is at most twice either rule's.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/lights/light_sampler.h"

namespace pf {

class LightChoice {
 public:
  // β = uniform_fraction, clamped to [0, 0.999].
  LightChoice(const LightSampler& lights, float uniform_fraction);

  struct Choice {
    size_t light = 0;
    float probability = 0;  // p_i: the width of the light's stratum of the float CDF
    float u = 0;            // the uniform's position inside that stratum, rescaled to [0, 1)
  };
  // The light whose stratum of [0, 1) holds u. A light too dim for a float stratum (< ~6e-8 of
  // the power with β = 0) is never chosen and its probability is 0.
  Choice Choose(float u) const;
  float probability(size_t light) const { return prob_[light]; }
  bool empty() const { return cdf_.empty(); }

  // The densities of this choice followed by SampleLight, for MIS with BSDF samples: per unit
  // area at a point of emitting triangle `tri`, and per solid angle of the environment towards wi.
  float PdfArea(uint32_t tri) const;
  float PdfEnvironment(const Vec3& wi) const;

 private:
  const LightSampler* lights_;
  std::vector<float> cdf_, prob_;
  size_t environment_light_ = 0;  // the environment's light number, if there is one
};

}  // namespace pf
