#pragma once
// Executes one task — build (or reuse) the task's photon map, render its pixel subset — and the
// single-process execution of a whole plan. Shared by pf-worker and `pf render`, so that a farm
// render and a local render of the same plan and seed are bit-identical (docs/design.md, G1).

#include <atomic>
#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/image/image.h"
#include "common/photon/photon_maps.h"
#include "common/plan/task_plan.h"
#include "common/render/light_sampler.h"
#include "common/render/photon_map_integrator.h"

namespace pf {

enum class IntegratorKind { kPath, kPhotonMap };

// What an `auto` setting became for a scene, and why (logged by pf and pf-worker).
struct AutoChoice {
  std::string setting, value, reason;
};

// Direct light `auto`: PhotonDirect from this many lights on, Monte Carlo below (docs/renderer.md,
// "auto settings"; measured in docs/results/estimators.md).
inline constexpr int kPhotonDirectMinLights = 8;

// Everything about *how* to render that is the same for all tasks of a job.
struct JobRenderSettings {
  IntegratorKind integrator = IntegratorKind::kPhotonMap;
  // Pixel samples and photons (issue #11): Owen-scrambled Sobol by default.
  SamplerKind sampler = SamplerKind::kSobol;
  uint64_t photons = 200000;
  PhotonMapKind structure = PhotonMapKind::kKdTree;
  // Widest extent: 2-4x faster queries than level % 3 in rooms with axis-aligned walls
  // (bench/photon_map_bench; the thesis suggests it for flat scenes, §2.3 footnote 2).
  KdSplitRule kd_split = KdSplitRule::kWidestExtent;
  CausticMapMode caustic = CausticMapMode::kAuto;
  int k = 100;
  float caustic_radius = 0.0f;  // 0 = DefaultCausticOptions
  int glossy_depth = 1;
  FeasibilityTest direction_test = FeasibilityTest::kInQuery;
  // Chapter 4 (see photon_map_integrator.h and direct_light.h).
  std::optional<DirectLightMode> direct;  // nullopt = auto (see Resolved)
  int shadow_rays = 16;                   // MC: per shading point; PhotonDirect: N_total
  float light_uniform_fraction = 0.0f;    // MC: defensive mixing β
  int photon_direct_k = 50;
  NonContributingMode non_contributing = NonContributingMode::kOneRandom;
  float photon_direct_cache = 0.25f;                           // neighbour-set cache radius fraction; 0 = off
  int local_pass_rays = 0;                                     // §4.3; 0 = off
  LocalPassLookup local_pass_lookup = LocalPassLookup::kFull;  // precomputed irradiance (Christensen 1999)
  bool occlusion_test = false;                                 // §4.1.1
  int adaptive_k_min = 0;                                      // §4.8; 0 = off

  // The settings with every `auto` made concrete for `scene`: a pure function of both, so every
  // worker and `pf render` decide alike. `choices` (optional) receives each decision and its reason.
  JobRenderSettings Resolved(const SceneDescription& scene, std::vector<AutoChoice>* choices = nullptr) const;

  // The integrator options these settings describe, for a scene with these bounds. Requires
  // resolved settings (std::logic_error otherwise).
  PhotonMapIntegratorOptions IntegratorOptions(const Bounds3& scene_bounds) const;
  // The photon-map options (everything but the seed and threads).
  PhotonMapsOptions MapsOptions() const;

  // Stable text form of the settings that change a photon map (cache key).
  std::string MapFingerprint() const;
};

// A scene ready to trace: description + Embree + lights. Built once per scene per process.
struct SceneRuntime {
  explicit SceneRuntime(SceneDescription description);
  SceneDescription description;
  EmbreeScene accel;
  LightSampler lights;
};

// LRU cache of photon maps by (scene key, map fingerprint, map seed). Thread-safe.
class PhotonMapCache {
 public:
  explicit PhotonMapCache(size_t capacity = 4) : capacity_(capacity) {}
  std::shared_ptr<const PhotonMaps> Find(const std::string& key);
  void Insert(const std::string& key, std::shared_ptr<const PhotonMaps> maps);
  std::vector<uint64_t> CachedSeeds() const;
  size_t size() const;

 private:
  struct Entry {
    std::string key;
    uint64_t seed;
    std::shared_ptr<const PhotonMaps> maps;
  };
  mutable std::mutex mutex_;
  std::list<Entry> entries_;  // most recent first
  size_t capacity_;
};

struct TaskOutput {
  std::vector<float> rgb_sums;  // 3 per pixel, subset order
  // The subset's pixel indices in subset order (PixelsOf), so that a local merge does not
  // expand the subset, or a skipping permutation of all W·H pixels, a second time.
  std::vector<uint32_t> pixel_indices;
  uint64_t pixels = 0;
  uint32_t samples = 0;  // per pixel
  uint64_t photons_emitted = 0, photons_stored = 0, rays = 0;
  uint64_t nonfinite_samples = 0;  // NaN/Inf samples dropped (RenderStats)
  double map_seconds = 0, render_seconds = 0;
  bool map_cache_hit = false;
};

// What a local plan render did, summed over its tasks (for the EXR header and the summary line).
struct LocalRenderTotals {
  uint64_t tasks = 0, maps_built = 0, photons_emitted = 0, photons_stored = 0, rays = 0,
           nonfinite_samples = 0;
  double map_seconds = 0, render_seconds = 0;
  void Add(const TaskOutput& out);
};

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
