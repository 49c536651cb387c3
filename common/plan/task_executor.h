#pragma once
// Executes one task — build (or reuse) the task's photon map, render its pixel subset — and the
// single-process execution of a whole plan. Shared by pf-worker and `pf render`, so that a farm
// render and a local render of the same plan and seed are bit-identical (docs/design.md, G1).
// Its inputs each have a header of their own: render/job_render_settings.h (how to render), scene_runtime.h
// (the scene ready to trace) and map_cache.h (photon maps kept between tasks).

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/image/image.h"
#include "common/photon/map_cache.h"
#include "common/plan/task_plan.h"
#include "common/render/job_render_settings.h"
#include "common/render/scene_runtime.h"

namespace pf {

struct TaskOutput {
  std::vector<float> rgb_sums;  // 3 per pixel, subset order
  // The subset's pixel indices in subset order (PixelsOf), so that a local merge does not
  // expand the subset, or a skipping permutation of all W·H pixels, a second time.
  std::vector<uint32_t> pixel_indices;
  uint64_t pixels = 0;
  uint32_t samples = 0;  // per pixel
  uint64_t photons_emitted = 0, photons_stored = 0, rays = 0;
  uint64_t nonfinite_samples = 0;                  // NaN/Inf samples dropped (RenderStats)
  uint64_t gathers = 0, cache_interpolations = 0;  // local pass (TraceCounters)
  double map_seconds = 0, render_seconds = 0;
  bool map_cache_hit = false;
};

// What a local plan render did, summed over its tasks (for the EXR header and the summary line).
struct LocalRenderTotals {
  uint64_t tasks = 0, maps_built = 0, photons_emitted = 0, photons_stored = 0, rays = 0,
           nonfinite_samples = 0, gathers = 0, cache_interpolations = 0;
  double map_seconds = 0, render_seconds = 0;
  void Add(const TaskOutput& out);
};

// The key under which ExecuteTask caches the maps of `map_seed` for a scene and *resolved*
// settings (JobRenderSettings::Resolved): a map obtained elsewhere (fetched from the coordinator,
// read from a disk cache) inserted under it is used as if it had been built here.
std::string MapCacheKey(const std::string& scene_key, const JobRenderSettings& resolved, uint64_t map_seed);

// Renders one task. `scene_key` identifies the scene for the cache (e.g. its bundle hash);
// `cache` may be null. `progress` (optional) counts finished pixels. `cancel` (optional) stops
// photon tracing and rendering soon after it is set: ExecuteTask then throws Cancelled and
// caches no map.
TaskOutput ExecuteTask(const SceneRuntime& scene, const std::string& scene_key, const CameraSpec& camera,
                       const JobRenderSettings& settings, const TaskSpec& task, int threads,
                       PhotonMapCache* cache = nullptr, std::atomic<uint64_t>* progress = nullptr,
                       const std::atomic<bool>* cancel = nullptr);

// The whole plan in this process, merged with the farm's Accumulator (same arithmetic).
Image RenderPlanLocally(const SceneRuntime& scene, const CameraSpec& camera,
                        const JobRenderSettings& settings, const PlanSpec& plan, uint64_t seed, int threads,
                        std::atomic<uint64_t>* progress = nullptr, LocalRenderTotals* totals = nullptr);

}  // namespace pf
