#include "common/render/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <numeric>

#include "common/core/error.h"
#include "common/core/rng.h"
#include "common/sampling/sample_layout.h"

namespace pf {
namespace {
// Keys the extra primary rays of "Emitters seen directly" apart from every sampler stream.
constexpr uint64_t kEmissionRayTag = 0x656d697373696f6eull;  // "emission"
}  // namespace

RenderStats RenderPixels(const Integrator& integrator, const Camera& camera, std::span<const uint32_t> pixels,
                         uint32_t sample_begin, uint32_t sample_end, uint64_t seed, int threads,
                         std::span<Rgb> sums, std::atomic<uint64_t>* progress,
                         const std::atomic<bool>* cancel, SamplerKind sampler_kind, PixelStreams streams) {
  const auto start = std::chrono::steady_clock::now();
  struct Local {
    TraceCounters counters;
    uint64_t nonfinite = 0;
  };
  tbb::enumerable_thread_specific<Local> locals;
  const int width = camera.width();
  const bool split_emission = integrator.SplitsPrimaryEmission() && streams == PixelStreams::kPerPixel;
  // Whether the pixel's fixed lattice of camera rays sees an emitting surface.
  auto sees_emitter = [&](int px, int py, TraceCounters& counters) {
    for (int j = 0; j < kEmitterPilotGrid * kEmitterPilotGrid; ++j) {
      const float u = (float(j % kEmitterPilotGrid) + 0.5f) / float(kEmitterPilotGrid);
      const float v = (float(j / kEmitterPilotGrid) + 0.5f) / float(kEmitterPilotGrid);
      bool surface = false;
      integrator.PrimaryEmission(camera.GenerateRay(px, py, u, v), counters, &surface);
      if (surface) return true;
    }
    return false;
  };
  // One pixel: its samples in order, summed into sums[i].
  auto render_pixel = [&](size_t i, Local& local, PixelBlockState* block) {
    const uint32_t p = pixels[i];
    const int px = int(p % uint32_t(width)), py = int(p / uint32_t(width));
    ++t_pixel_epoch;
    Rgb sum = sums[i];
    // The pixel's keys and slot seeds, once (PixelStreams: the pixel's own or the call's shared one).
    const PixelStream stream(sampler_kind, seed, streams == PixelStreams::kShared ? kSharedStreamPixel : p);
    const bool split = split_emission && sees_emitter(px, py, local.counters);
    for (uint32_t s = sample_begin; s < sample_end; ++s) {
      Sampler sampler = Sampler::ForPixelSample(stream, s);
      const Sample2 uv = sampler.Get2D(kPixelSlot);
      const Ray ray = camera.GenerateRay(px, py, uv.u, uv.v);
      Rgb L = block ? integrator.LiInBlock(ray, sampler, local.counters, *block)
                    : integrator.Li(ray, sampler, local.counters);
      if (split) {
        bool surface = false;
        L = L - integrator.PrimaryEmission(ray, local.counters, &surface);
        Rng rng = Rng::ForKey(HashKey(seed, p, s, kEmissionRayTag));
        Rgb emission(0.0f);
        for (int j = 0; j < kEmissionRaysPerSample; ++j) {
          const float u = (float(j % kEmissionStrata) + rng.Uniform()) / float(kEmissionStrata);
          const float v = (float(j / kEmissionStrata) + rng.Uniform()) / float(kEmissionStrata);
          emission += integrator.PrimaryEmission(camera.GenerateRay(px, py, u, v), local.counters, &surface);
        }
        L += emission * (1.0f / float(kEmissionRaysPerSample));
      }
      if (L.IsFinite()) {
        sum += L;
      } else {
        ++local.nonfinite;
      }
    }
    sums[i] = sum;
  };
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  if (!integrator.NewPixelBlockState()) {
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, pixels.size(), 16), [&](const auto& range) {
        if (cancel && cancel->load(std::memory_order_relaxed)) return;
        Local& local = locals.local();
        for (size_t i = range.begin(); i != range.end(); ++i) render_pixel(i, local, nullptr);
        if (progress) progress->fetch_add(range.size(), std::memory_order_relaxed);
      });
    });
  } else {
    // Pixel blocks (integrator.h, PixelBlockState): the subset's pixels grouped by the
    // kPixelBlockSide² image tile they lie in, in subset order within a block; each block is
    // rendered whole by one thread with a fresh state. Which pixels share a state thus depends
    // only on the subset, never on threads or on the task's neighbours.
    const uint32_t tiles_x = (uint32_t(width) + kPixelBlockSide - 1) / kPixelBlockSide;
    auto block_of = [&](uint32_t p) {
      return (p / uint32_t(width)) / kPixelBlockSide * tiles_x + (p % uint32_t(width)) / kPixelBlockSide;
    };
    std::vector<uint32_t> order(pixels.size());
    std::iota(order.begin(), order.end(), 0u);
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t a, uint32_t b) { return block_of(pixels[a]) < block_of(pixels[b]); });
    std::vector<size_t> starts;
    for (size_t j = 0; j < order.size(); ++j)
      if (j == 0 || block_of(pixels[order[j]]) != block_of(pixels[order[j - 1]])) starts.push_back(j);
    starts.push_back(order.size());
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, starts.size() - 1, 1), [&](const auto& range) {
        Local& local = locals.local();
        for (size_t b = range.begin(); b != range.end(); ++b) {
          if (cancel && cancel->load(std::memory_order_relaxed)) return;
          const std::unique_ptr<PixelBlockState> block = integrator.NewPixelBlockState();
          for (size_t j = starts[b]; j != starts[b + 1]; ++j) render_pixel(order[j], local, block.get());
          if (progress) progress->fetch_add(starts[b + 1] - starts[b], std::memory_order_relaxed);
        }
      });
    });
  }
  if (cancel && cancel->load()) throw Cancelled();
  RenderStats stats;
  for (const Local& l : locals) {
    stats.counters += l.counters;
    stats.nonfinite_samples += l.nonfinite;
  }
  stats.samples = uint64_t(pixels.size()) * (sample_end - sample_begin);
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

Image RenderImage(const Integrator& integrator, const Camera& camera, const RenderOptions& options,
                  RenderStats* stats, std::atomic<uint64_t>* progress) {
  Image image(camera.width(), camera.height());
  std::vector<uint32_t> pixels(image.size());
  std::iota(pixels.begin(), pixels.end(), 0u);
  const RenderStats s = RenderPixels(integrator, camera, pixels, 0, options.spp, options.seed,
                                     options.threads, image.pixels(), progress, nullptr, options.sampler);
  const float inv = options.spp > 0 ? 1.0f / float(options.spp) : 0.0f;
  for (Rgb& c : image.pixels()) c *= inv;
  if (stats) *stats = s;
  return image;
}

}  // namespace pf
