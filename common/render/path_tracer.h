#pragma once
// The reference path tracer (`--integrator path`): unbiased, next-event estimation with
// multiple importance sampling (power heuristic), Russian roulette, delta lobes followed
// exactly. Every photon-map image is measured against it.
// Next-event estimation picks a light by LightChoice with half of its probability uniform over the
// lights (light_choice.h): by power alone, a sky of hundreds of watts starves a spot lamp or an
// emitting panel that lights part of the scene as brightly (docs/results/blender-cycles.md).

#include "common/accel/embree_scene.h"
#include "common/lights/light_choice.h"
#include "common/lights/light_sampler.h"
#include "common/materials/bsdf.h"
#include "common/render/integrator.h"
#include "common/sampling/sample_layout.h"

namespace pf {

struct PathTracerOptions {
  // Russian roulette starts after this many bounces; survival = min(1, max channel of the
  // throughput). Higher values cost time, lower ones add variance; never bias.
  int rr_start_depth = 4;
  // Hard safety cap on path length. Paths are terminated by RR long before this; the cap only
  // protects against pathological inputs (it is a negligible bias: throughput ~ 0 by then).
  int max_depth = 1024;
  // β of the light choice for next-event estimation (light_choice.h). Not a render setting (the
  // photon-map integrator's `light-uniform-fraction` does not reach it): one value serves every
  // scene, since the mixture's second moment is at most twice either pure rule's.
  float nee_uniform_fraction = 0.5f;
};

class PathTracer final : public Integrator {
 public:
  PathTracer(const EmbreeScene& scene, const LightSampler& lights, PathTracerOptions options = {});
  Rgb Li(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters) const override;
  const char* name() const override { return "path"; }

 private:
  // One light sample at `hit` (next-event estimation), MIS-weighted against BSDF sampling, times
  // the path's throughput (multiplied first, in the order the golden images were recorded with).
  Rgb LightSampleEstimate(const SurfaceHit& hit, const Bsdf& bsdf, const Vec3& wo, const Rgb& throughput,
                          Sampler& sampler, const PathVertexSlots& slots, TraceCounters& counters) const;

  const EmbreeScene& scene_;
  const LightSampler& lights_;
  PathTracerOptions options_;
  LightChoice choice_;
};

}  // namespace pf
