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
#include "common/plan/stop_targets.h"
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

// A render in one process stops like a farm job (docs/farm.md, "Stop rules"): at the end of a
// whole unit of its plan — a map (a progressive pass), a skipping round — once the time budget is
// used up or the targets are met. The image is then exactly the plan's with that many units (the
// same plan with --maps/--passes/--rounds = units_done), whatever the threads.
struct LocalStopRule {
  double time_budget_seconds = 0;  // 0 = none; wall time from the first task
  StopTargets targets;
  bool any() const { return time_budget_seconds > 0 || targets.any(); }
};
struct LocalStopReport {
  std::string unit = "maps";  // what units_* count: maps, passes, rounds
  uint64_t units_done = 0, units_planned = 0;
  std::string stopped_by;    // "" (the whole plan ran), "time budget", "targets met"
  ErrorEstimates estimates;  // the Accumulator's at the end
  bool targets_met = false;
};

// "" if `rule` can stop `plan` in one process; else why not (the hierarchical plan's levels are
// not units that leave a complete image).
std::string LocalStopProblem(const LocalStopRule& rule, const PlanSpec& plan);

// The whole plan in this process, merged with the farm's Accumulator (same arithmetic), or its
// first units until `stop` ends it (LocalStopProblem must be "").
Image RenderPlanLocally(const SceneRuntime& scene, const CameraSpec& camera,
                        const JobRenderSettings& settings, const PlanSpec& plan, uint64_t seed, int threads,
                        std::atomic<uint64_t>* progress = nullptr, LocalRenderTotals* totals = nullptr,
                        const LocalStopRule& stop = {}, LocalStopReport* report = nullptr);

}  // namespace pf
