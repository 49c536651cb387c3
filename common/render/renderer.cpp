#include "common/render/renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <chrono>
#include <numeric>

#include "common/core/error.h"
#include "common/sampling/sample_layout.h"

namespace pf {

RenderStats RenderPixels(const Integrator& integrator, const Camera& camera, std::span<const uint32_t> pixels,
                         uint32_t sample_begin, uint32_t sample_end, uint64_t seed, int threads,
                         std::span<Rgb> sums, std::atomic<uint64_t>* progress,
                         const std::atomic<bool>* cancel, SamplerKind sampler_kind) {
  const auto start = std::chrono::steady_clock::now();
  struct Local {
    TraceCounters counters;
    uint64_t nonfinite = 0;
  };
  tbb::enumerable_thread_specific<Local> locals;
  const int width = camera.width();
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, pixels.size(), 16), [&](const auto& range) {
      if (cancel && cancel->load(std::memory_order_relaxed)) return;
      Local& local = locals.local();
      for (size_t i = range.begin(); i != range.end(); ++i) {
        const uint32_t p = pixels[i];
        const int px = int(p % uint32_t(width)), py = int(p / uint32_t(width));
        ++t_pixel_epoch;
        Rgb sum = sums[i];
        const PixelStream stream(sampler_kind, seed, p);  // the pixel's keys and slot seeds, once
        for (uint32_t s = sample_begin; s < sample_end; ++s) {
          Sampler sampler = Sampler::ForPixelSample(stream, s);
          const Sample2 uv = sampler.Get2D(kPixelSlot);
          const Rgb L = integrator.Li(camera.GenerateRay(px, py, uv.u, uv.v), sampler, local.counters);
          if (L.IsFinite()) {
            sum += L;
          } else {
            ++local.nonfinite;
          }
        }
        sums[i] = sum;
      }
      if (progress) progress->fetch_add(range.size(), std::memory_order_relaxed);
    });
  });
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
