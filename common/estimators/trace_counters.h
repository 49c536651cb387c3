#pragma once
// What a pixel's estimators share with the integrator that drives them: the counters of the rays
// they trace, and the pixel epoch that bounds the life of their per-pixel caches. Below
// render/integrator.h so that the estimators (direct light, radiance estimate) need no integrator.

#include <cstdint>

namespace pf {

// Counters gathered per work item and summed by the driver (no shared atomics on the hot path).
struct TraceCounters {
  uint64_t rays = 0;         // closest-hit queries
  uint64_t shadow_rays = 0;  // occlusion queries
  // Local pass (§4.3): shading points that sent their own gather rays, and those that
  // interpolated the irradiance cache instead.
  uint64_t gathers = 0, cache_interpolations = 0;
  void operator+=(const TraceCounters& o) {
    rays += o.rays;
    shadow_rays += o.shadow_rays;
    gathers += o.gathers;
    cache_interpolations += o.cache_interpolations;
  }
};

// Bumped by the render driver before each pixel, per thread. Integrator-side caches (e.g. the
// PhotonDirect neighbour set) are reused only within one pixel, so a result never depends on
// which pixels a thread happened to render before it (determinism, docs/design.md, G1).
inline thread_local uint64_t t_pixel_epoch = 0;

}  // namespace pf
