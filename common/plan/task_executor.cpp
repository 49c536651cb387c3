#include "common/plan/task_executor.h"

#include "common/plan/hierarchical.h"

#include <spdlog/spdlog.h>

#include <bit>
#include <chrono>
#include <stdexcept>

#include "common/camera/camera.h"
#include "common/photon/map_key.h"
#include "common/plan/accumulator.h"
#include "common/render/integrator_factory.h"
#include "common/render/progressive_radius.h"
#include "common/render/render_settings_rules.h"
#include "common/render/renderer.h"

namespace pf {

namespace {

// The camera as text for a map cache key (exact bits: world points in double, the rest in float).
std::string CameraKey(const CameraSpec& c) {
  std::string s;
  for (double v : {c.eye.x, c.eye.y, c.eye.z, c.look_at.x, c.look_at.y, c.look_at.z})
    s += std::to_string(std::bit_cast<uint64_t>(v)) + ",";
  for (float v : {c.up.x, c.up.y, c.up.z, c.vfov_degrees})
    s += std::to_string(std::bit_cast<uint32_t>(v)) + ",";
  return s;
}

// The photon maps of `task`: from `cache` (may be null) or built, and then cached; `out` gets
// the photon counts and the time they took.
std::shared_ptr<const PhotonMaps> TaskMaps(const SceneRuntime& scene, const std::string& scene_key,
                                           const Camera& camera, const CameraSpec& camera_spec,
                                           const JobRenderSettings& settings, const TaskSpec& task,
                                           int threads, PhotonMapCache* cache,
                                           const std::atomic<bool>* cancel, TaskOutput& out) {
  std::string key = MapCacheKey(scene_key, settings, task.map_seed);
  // An importance-driven map depends on the camera too (its importons, §4.7); such maps are
  // always traced where they are used (never distributed: MapTracingMode, job_render_settings.h).
  if (settings.importance != ImportanceMode::kOff)
    key += "|camera=" + std::to_string(camera.width()) + "x" + std::to_string(camera.height()) + "," +
           CameraKey(camera_spec);
  // Emission + direct light alone (radiance_part.h) reads no map, except PhotonDirect's light
  // choice (§4.2.3), which reads the direct photons.
  const bool needs_map =
      task.part != RadiancePart::kUnmapped || settings.direct == DirectLightMode::kPhotonDirect;
  std::shared_ptr<const PhotonMaps> maps = !needs_map ? std::make_shared<const PhotonMaps>()
                                           : cache    ? cache->Find(key)
                                                      : nullptr;
  out.map_cache_hit = needs_map && maps != nullptr;
  if (!maps) {
    PhotonMapsOptions mo = settings.MapsOptions();
    mo.tracing.map_seed = task.map_seed;
    mo.tracing.threads = threads;
    mo.tracing.cancel = cancel;
    maps = std::make_shared<const PhotonMaps>(PhotonMaps::Build(scene.accel, scene.lights, mo, &camera));
    if (cache) cache->Insert(key, maps);
  }
  out.photons_emitted = maps->stats.emitted;
  out.photons_stored = maps->stats.stored_global + maps->stats.stored_caustic;
  out.map_seconds = out.map_cache_hit ? 0.0 : maps->stats.trace_seconds + maps->stats.build_seconds;
  return maps;
}

}  // namespace

std::string MapCacheKey(const std::string& scene_key, const JobRenderSettings& resolved, uint64_t map_seed) {
  return MapKey{scene_key, resolved.MapFingerprint(), map_seed}.Text();
}

TaskOutput ExecuteTask(const SceneRuntime& scene, const std::string& scene_key, const CameraSpec& camera_spec,
                       const JobRenderSettings& settings_as_given, const TaskSpec& task, int threads,
                       PhotonMapCache* cache, std::atomic<uint64_t>* progress,
                       const std::atomic<bool>* cancel) {
  TaskOutput out;
  const Camera camera(camera_spec, scene.description.origin);  // into the scene's frame (scene_frame.h)
  std::vector<uint32_t> pixels = PixelsOf(task.pixels, camera.width(), camera.height());
  std::vector<Rgb> sums(pixels.size());
  // A hierarchical detail task renders level-l points and their parents with one map: common
  // random numbers there (PixelStreams::kShared, renderer.h) so that the detail's Monte Carlo
  // noise cancels like the map's error does (Wald 1999, §4.5; docs/renderer.md "Hierarchical
  // plan"). Level-0 and localization tasks estimate pixels directly: independent streams.
  const PixelStreams streams = task.pixels.kind == PixelSubset::Kind::kHierarchyLevel && task.pixels.level > 0
                                   ? PixelStreams::kShared
                                   : PixelStreams::kPerPixel;
  if (task.part != RadiancePart::kAll) CheckRadiancePartsApart(settings_as_given, "plan.hierarchical.part");
  const IntegratorEntry& integrator_entry = Integrators().FindKind(settings_as_given.integrator);
  // Resolved makes the photon-map settings' `auto` concrete; it leaves the path tracer's as given.
  const JobRenderSettings settings = settings_as_given.Resolved(scene.description);
  std::shared_ptr<const PhotonMaps> maps;
  if (integrator_entry.UsesPhotonMaps())
    maps = TaskMaps(scene, scene_key, camera, camera_spec, settings, task, threads, cache, cancel, out);
  const std::unique_ptr<const Integrator> integrator = integrator_entry.build(
      settings,
      {.scene = &scene.accel,
       .lights = &scene.lights,
       .maps = maps.get(),
       .threads = threads,
       .part = task.part,
       .pass_radius =
           task.progressive ? ProgressivePassRadius(settings, scene.accel.bounds(), task.map_index) : 0.0f});
  const RenderStats stats =
      RenderPixels(*integrator, camera, pixels, task.sample_begin, task.sample_end, task.pixel_seed, threads,
                   sums, progress, cancel, settings.sampler, streams);
  out.pixels = pixels.size();
  out.samples = task.sample_end - task.sample_begin;
  out.rgb_sums.resize(pixels.size() * 3);
  for (size_t i = 0; i < pixels.size(); ++i) {
    out.rgb_sums[3 * i] = sums[i].r;
    out.rgb_sums[3 * i + 1] = sums[i].g;
    out.rgb_sums[3 * i + 2] = sums[i].b;
  }
  out.rays = stats.counters.rays + stats.counters.shadow_rays;
  out.nonfinite_samples = stats.nonfinite_samples;
  out.gathers = stats.counters.gathers;
  out.cache_interpolations = stats.counters.cache_interpolations;
  out.render_seconds = stats.seconds;
  out.pixel_indices = std::move(pixels);
  return out;
}

void LocalRenderTotals::Add(const TaskOutput& out) {
  ++tasks;
  if (!out.map_cache_hit && out.photons_emitted > 0) {
    ++maps_built;
    photons_emitted += out.photons_emitted;
    photons_stored += out.photons_stored;
  }
  rays += out.rays;
  nonfinite_samples += out.nonfinite_samples;
  gathers += out.gathers;
  cache_interpolations += out.cache_interpolations;
  map_seconds += out.map_seconds;
  render_seconds += out.render_seconds;
}

std::string LocalStopProblem(const LocalStopRule& rule, const PlanSpec& plan) {
  if (rule.any() && plan.kind == PlanKind::kHierarchical)
    return "the hierarchical plan cannot stop early in one process (its levels complete the image "
           "together); give --maps, or run it on the farm, where a time budget keeps what was merged";
  return StopTargetsProblem(rule.targets, plan, "stop");
}

Image RenderPlanLocally(const SceneRuntime& scene, const CameraSpec& camera,
                        const JobRenderSettings& settings, const PlanSpec& plan, uint64_t seed, int threads,
                        std::atomic<uint64_t>* progress, LocalRenderTotals* totals, const LocalStopRule& stop,
                        LocalStopReport* report) {
  if (const std::string problem = LocalStopProblem(stop, plan); !problem.empty()) throw InputError(problem);
  PhotonMapCache cache(1);
  if (plan.kind == PlanKind::kHierarchical) {
    // Wald 1999, §4.5: the static tasks, then each level's localization tasks as the merged
    // results imply them (the same HierarchicalTasks the coordinator asks after every merge).
    HierarchicalAssembly assembly(plan, camera.width, camera.height);
    size_t done = 0;
    for (;;) {
      const std::vector<TaskSpec> tasks =
          HierarchicalTasks(plan, camera.width, camera.height, seed, assembly);
      if (tasks.size() == done) break;
      for (size_t i = done; i < tasks.size(); ++i) {
        const TaskOutput out =
            ExecuteTask(scene, "local", camera, settings, tasks[i], threads, &cache, progress);
        assembly.Add(tasks[i], out.pixel_indices, out.rgb_sums, out.samples);
        if (totals) totals->Add(out);
      }
      done = tasks.size();
    }
    std::string per_level;
    uint64_t localized = 0;
    for (uint32_t l = 1; l <= plan.levels; ++l) {
      const size_t n = assembly.Localized(l).size();
      localized += n;
      if (l > 1) per_level += ',';
      per_level += std::to_string(n);
    }
    spdlog::info("hierarchical: {} points localized (levels 1..{}: {})", localized, plan.levels, per_level);
    return assembly.Resolve();
  }
  const auto t0 = std::chrono::steady_clock::now();
  Accumulator acc(plan, camera.width, camera.height, settings.progressive_alpha);
  const std::vector<TaskSpec> tasks = ExpandPlan(plan, camera.width, camera.height, seed);
  // A unit ends where the next task starts another map (another round for skipping, whose tasks
  // each have their own map); ExpandPlan lists a unit's tasks together.
  const bool by_round = plan.kind == PlanKind::kSkipping;
  const auto unit_of = [by_round](const TaskSpec& t) { return by_round ? uint64_t(t.round) : t.map_index; };
  LocalStopReport rep;
  rep.unit = by_round ? "rounds" : plan.kind == PlanKind::kProgressive ? "passes" : "maps";
  rep.units_planned = tasks.empty() ? 0 : unit_of(tasks.back()) + 1;
  for (size_t i = 0; i < tasks.size(); ++i) {
    const TaskSpec& task = tasks[i];
    const TaskOutput out = ExecuteTask(scene, "local", camera, settings, task, threads, &cache, progress);
    const ResultCheck check =
        Accumulator::ValidateTaskResult(out.rgb_sums, out.pixel_indices.size(), out.samples);
    if (!check.ok()) throw InputError(check.reason);
    acc.AddValidated(task, out.pixel_indices, out.rgb_sums, out.samples);
    if (totals) totals->Add(out);
    if (i + 1 < tasks.size() && unit_of(tasks[i + 1]) == unit_of(task)) continue;
    rep.units_done = unit_of(task) + 1;
    if (!stop.any() || i + 1 == tasks.size()) continue;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (stop.targets.any() && StopTargetsMet(stop.targets, acc.Estimates())) {
      rep.stopped_by = "targets met";
      break;
    }
    if (stop.time_budget_seconds > 0 && elapsed >= stop.time_budget_seconds) {
      rep.stopped_by = "time budget";
      break;
    }
  }
  rep.estimates = acc.Estimates();
  rep.targets_met = StopTargetsMet(stop.targets, rep.estimates);
  if (report) *report = rep;
  return acc.Resolve();
}

}  // namespace pf
