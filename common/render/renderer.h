#pragma once
// Drives an integrator over pixels. The unit of work the farm will distribute is a *pixel
// subset × sample range*: RenderPixels returns per-pixel sums in subset order, so a task result
// never carries a full image (docs/design.md, §1 Result). RenderImage is the single-process special case.
//
// Determinism: sample s of pixel p draws from Sampler::ForPixelSample(kind, seed, p, s) (a value
// depends only on seed, p, s and the slot) and the samples of a pixel are summed in order, so any
// thread count gives bit-identical sums.
//
// Emitters seen directly (docs/renderer.md, same title): with an integrator that splits off the
// first hit's emission (Integrator::SplitsPrimaryEmission) and per-pixel streams, a pixel whose
// kEmitterPilotGrid² lattice of camera rays hits an emitting surface estimates that emission with
// kEmissionRaysPerSample jittered-stratified primary rays per sample instead of the sample's one:
// sample s adds Li − E(ray_s) + mean_j E(ray_sj), whose expectation is Li's. The lattice is a fixed
// function of the pixel, so choosing the pixels adds no bias; the extra rays are intersections
// only (no photon query, no shading), drawn from Rng::ForKey(seed, p, s, tag).

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "common/camera/camera.h"
#include "common/image/image.h"
#include "common/render/integrator.h"
#include "common/sampling/sampler.h"

namespace pf {

inline constexpr uint32_t kPixelBlockSide = 16;
// Emitters seen directly (above).
inline constexpr int kEmitterPilotGrid = 2;
inline constexpr int kEmissionStrata = 4;  // kEmissionStrata² rays per sample
inline constexpr int kEmissionRaysPerSample = kEmissionStrata * kEmissionStrata;

struct RenderOptions {
  uint32_t spp = 16;
  uint64_t seed = 1;
  int threads = 0;  // 0 = all hardware threads
  SamplerKind sampler = SamplerKind::kSobol;
};

// Which random numbers the pixels of one RenderPixels call draw.
//  kPerPixel: sample s of pixel p from Sampler::ForPixelSample(kind, seed, p, s): independent
//             pixels, white noise (the default; every plan except a hierarchy's details).
//  kShared:   every listed pixel draws sample s from the same stream (seed, kSharedStreamPixel, s):
//             the same sub-pixel offset, light samples and BSDF samples at every pixel. Common
//             random numbers for a hierarchical detail f_j(p) − Σ w f_j(q) (Wald 1999, §4.5): the
//             thesis uses the same map at p and its parents so that the map's error cancels in the
//             detail; the same random numbers make the Monte Carlo part (direct light's shadow rays,
//             §4.2.1) cancel too wherever the image is smooth, instead of adding three times.
enum class PixelStreams { kPerPixel, kShared };
// No pixel index reaches it (images are far smaller than 2^32 pixels).
inline constexpr uint32_t kSharedStreamPixel = 0xffffffffu;

struct RenderStats {
  double seconds = 0;
  uint64_t samples = 0;
  uint64_t nonfinite_samples = 0;  // dropped (counted, never averaged in)
  TraceCounters counters;
};

// Adds the radiance of samples [sample_begin, sample_end) of each listed pixel (index y·W + x)
// into sums[i]. `progress`, if given, is incremented by the number of pixels finished.
// `cancel`, if given, is checked before each block of 16 pixels; once it is set, the remaining
// blocks are skipped and RenderPixels throws Cancelled (`sums` then holds a partial result).
// An integrator with per-block state (Integrator::NewPixelBlockState, e.g. the irradiance cache)
// gets one state per kPixelBlockSide² image tile of the listed pixels, the tile's pixels in
// list order on one thread.
RenderStats RenderPixels(const Integrator& integrator, const Camera& camera, std::span<const uint32_t> pixels,
                         uint32_t sample_begin, uint32_t sample_end, uint64_t seed, int threads,
                         std::span<Rgb> sums, std::atomic<uint64_t>* progress = nullptr,
                         const std::atomic<bool>* cancel = nullptr, SamplerKind sampler = SamplerKind::kSobol,
                         PixelStreams streams = PixelStreams::kPerPixel);

// Whole image, averaged over options.spp samples per pixel.
Image RenderImage(const Integrator& integrator, const Camera& camera, const RenderOptions& options,
                  RenderStats* stats = nullptr, std::atomic<uint64_t>* progress = nullptr);

}  // namespace pf
