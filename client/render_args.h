#pragma once
// The options shared by `pf render` and `pf submit` (scene, camera, integrator and photon-map
// settings, plan, stop rule) and their translation into a photonfarm.v1.JobSpec. The local plan
// render (`pf render --local-only`) and the farm run the *same* JobSpec through the same
// proto → core conversion (proto/convert.h) as the coordinator, so their inputs are identical
// by construction (docs/design.md, G1).

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "common/plan/task_executor.h"
#include "common/scene/scene.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.pb.h"

namespace pf {

struct RenderArgs {
  std::string scene;
  std::string integrator = "path";
  std::string sampler = "sobol";
  uint32_t spp = 16;
  bool spp_given = false, photons_given = false, k_given = false;  // on the command line
  std::string output;
  std::string png;
  bool no_png = false;
  int threads = 0;
  uint64_t seed = 1;
  std::string camera_name;
  std::string eye, look_at, up, res;
  float fov = 0.0f;
  bool quiet = false;
  // Photon map (--integrator photonmap).
  uint64_t photons = 200000;
  int k = 100;
  std::string map = "kdtree";
  std::string kd_split = "widest";
  std::string caustic = "auto";
  float caustic_radius = 0.0f;
  int glossy_depth = 1;
  std::string direction_test = "in-query";
  // Chapter 4 estimators (Wald 1999, §4.1–4.3, §4.8).
  std::string direct = "auto";
  int shadow_rays = 16;
  float light_uniform = 0.0f;
  int photon_direct_k = 50;
  std::string non_contributing = "one-random";
  float photon_direct_cache = 0.25f;
  int local_pass = 0;
  std::string local_pass_lookup = "full";
  std::string site_occlusion_test = "on";
  bool irradiance_cache = false;
  float irradiance_cache_error = 0.2f;
  bool occlusion_test = false;
  int adaptive_k_min = 0;
  // Importance-driven photon maps (Wald 1999, §4.7).
  std::string importance = "off";
  double importance_min_probability = 0.05;
  double importance_strength = 4.0;
  uint64_t importons = 0;
  // Caustic splitting (Wald 1999, §4.6).
  uint32_t caustic_split = 1;
  std::string caustic_split_method = "brute";
  // Plan (farm and --local-only); plan.empty() = the classic single-process render.
  std::string plan;
  uint32_t maps = 1;
  uint32_t stride = 2;
  uint32_t rounds = 1;
  uint32_t tile = 64;
  int tail_tile = -1;  // multiple-maps: -1 = tile/2 on a farm (tail tiles), 0 = off
  // Hierarchical plan (Wald 1999, 4.5; common/plan/hierarchical.h).
  uint32_t levels = 4;
  uint32_t dims = 2;
  uint32_t base_samples = 8;
  uint32_t min_samples = 1;
  double decay = 2;
  double localize_threshold = 4;
  double localize_contrast = 0.25;
  std::string hier_part = "all";     // all | indirect (common/plan/hierarchical.h, "Parts")
  uint32_t hier_direct_samples = 1;  // with indirect: emission + direct light samples per pixel
  // Stop rule and scheduling (farm).
  uint32_t max_rounds = 0;
  double time_budget = 0;
  double target_noise = 0;
  int32_t priority = 0;
  std::string name;
  // Where to run.
  int workers = 0;
  bool local_only = false;
  std::string coordinator_bin, worker_bin;
  std::vector<std::string> coordinator_args, worker_args;
  bool keep_farm_dir = false;
  // --plan auto (docs/farm.md, "Choosing the plan"): the plan-shape flags given on the command line (--maps,
  // --stride, …), which auto would ignore: an error with it.
  std::vector<std::string> plan_flags_given;
  bool submit = false;  // `pf submit`: --plan defaults to auto, as with --workers
  // --map-tracing auto|local|distributed.
  std::string map_tracing = "auto";
};

// A scene manifest's "settings" (spp for a plain render, photons, k) become the defaults of the
// flags not given;
// logged. No-op for a geometry file. InputError if a value is out of the flags' range.
void ApplyManifestSettings(RenderArgs& a);

// Scene, camera, integrator and photon-map options (render and submit).
void AddSceneOptions(CLI::App* app, RenderArgs& a);

// The help section of the options that configure the photon-map integrator only.
inline constexpr const char* kPhotonMapOptionGroup = "Photon-map integrator (--integrator photonmap)";
// A photon-map option given on the command line of a path-traced render: a usage error
// (CLI::ValidationError naming the option), not a setting silently ignored. An error rather than
// a warning because the image would not show what was asked for; manifest `settings` stay
// allowed, since they describe the scene for either integrator.
void RejectPhotonMapOptionsForPath(const CLI::App& cmd, const RenderArgs& a);

// --plan, --maps, --stride, --rounds, --tile, stop rule, --priority, --name.
void AddPlanOptions(CLI::App* app, RenderArgs& a);

// The scene's camera after --camera/--eye/--look-at/--up/--fov/--res.
CameraSpec ChooseCamera(const SceneDescription& scene, const RenderArgs& a);

// Loads the scene (InputError with file:line if malformed), chooses the camera and returns the
// job (scene_hash left empty) and the scene's bundle.
struct PreparedJob {
  photonfarm::v1::JobSpec spec;
  SceneBundle bundle;
  SceneDescription scene;
};
PreparedJob PrepareJob(const RenderArgs& a);

// The integrator and photon-map options as the job's RenderSettings (auto values left auto).
void RenderSettingsFromArgs(const RenderArgs& a, photonfarm::v1::RenderSettings* out);

// Logs what each `auto` setting becomes for this scene, and why; returns the resolved settings.
JobRenderSettings ResolveAndLog(const JobRenderSettings& settings, const SceneDescription& scene);

std::string FormatVec(const Vec3& v);
std::string FormatVec(const Vec3d& v);

}  // namespace pf
