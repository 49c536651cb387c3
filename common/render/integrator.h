#pragma once
// What every pixel-by-pixel integrator provides: radiance along a camera ray, drawing its random
// numbers from the pixel sample's own sampler (so results never depend on threads), by the slots
// of common/sampling/sample_layout.h.

#include <cstdint>
#include <memory>

#include "common/accel/ray.h"
#include "common/core/math.h"
#include "common/sampling/sampler.h"

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

// What an integrator carries from pixel to pixel within one block of pixels (the irradiance
// cache). RenderPixels renders each block whole, on one thread, in a fixed pixel order, so such
// state never makes a result depend on threads, workers or scheduling.
class PixelBlockState {
 public:
  virtual ~PixelBlockState() = default;
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual Rgb Li(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters) const = 0;
  // Integrators that reuse work between the pixels of a block return a fresh state per block
  // (nullptr: none, pixels are independent); RenderPixels then calls LiInBlock.
  virtual std::unique_ptr<PixelBlockState> NewPixelBlockState() const { return nullptr; }
  virtual Rgb LiInBlock(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters,
                        PixelBlockState& /*block*/) const {
    return Li(camera_ray, sampler, counters);
  }
  virtual const char* name() const = 0;
};

}  // namespace pf
