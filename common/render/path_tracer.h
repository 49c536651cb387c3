#pragma once
// The reference path tracer (`--integrator path`): unbiased, next-event estimation with
// multiple importance sampling (power heuristic), Russian roulette, delta lobes followed
// exactly. Every photon-map image is measured against it.

#include "common/accel/embree_scene.h"
#include "common/lights/light_sampler.h"
#include "common/render/integrator.h"

namespace pf {

struct PathTracerOptions {
  // Russian roulette starts after this many bounces; survival = min(1, max channel of the
  // throughput). Higher values cost time, lower ones add variance; never bias.
  int rr_start_depth = 4;
  // Hard safety cap on path length. Paths are terminated by RR long before this; the cap only
  // protects against pathological inputs (it is a negligible bias: throughput ~ 0 by then).
  int max_depth = 1024;
};

class PathTracer final : public Integrator {
 public:
  PathTracer(const EmbreeScene& scene, const LightSampler& lights, PathTracerOptions options = {});
  Rgb Li(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters) const override;
  const char* name() const override { return "path"; }

 private:
  const EmbreeScene& scene_;
  const LightSampler& lights_;
  PathTracerOptions options_;
};

}  // namespace pf
