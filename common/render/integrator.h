#pragma once
// What every pixel-by-pixel integrator provides: radiance along a camera ray, drawing its random
// numbers from the pixel sample's own sampler (so results never depend on threads), by the slots
// of common/sampling/sample_layout.h.

#include <cstdint>
#include <memory>

#include "common/accel/ray.h"
#include "common/core/math.h"
#include "common/estimators/trace_counters.h"
#include "common/sampling/sampler.h"

namespace pf {

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
  // Emitters seen directly (docs/renderer.md, "Emitters seen directly"). An integrator that says
  // true here lets RenderPixels estimate the emission a camera ray sees at its first hit apart
  // from the rest of Li, with more (cheap) primary rays in the pixels that see an emitting
  // surface. PrimaryEmission must return exactly what Li adds for it — the first hit's own
  // emission, or the environment an escaping camera ray sees — and set `surface_emitter` when the
  // ray hit an emitting surface.
  virtual bool SplitsPrimaryEmission() const { return false; }
  virtual Rgb PrimaryEmission(const Ray& /*camera_ray*/, TraceCounters& /*counters*/,
                              bool* surface_emitter) const {
    *surface_emitter = false;
    return Rgb(0.0f);
  }
  virtual const char* name() const = 0;
};

}  // namespace pf
