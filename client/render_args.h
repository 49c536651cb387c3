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

#include "client/settings_args.h"
#include "common/plan/task_executor.h"
#include "common/scene/scene.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.pb.h"

namespace pf {

struct RenderArgs {
  std::string scene;
  // auto: chosen from the scene by ChooseIntegrator (integrator_choice.h), logged and recorded.
  std::string integrator = "auto";
  uint32_t spp = 16;
  bool spp_given = false;  // on the command line
  std::string output;
  std::string png;
  bool no_png = false;
  int threads = 0;
  uint64_t seed = 1;
  std::string camera_name;
  std::string eye, look_at, up, res;
  // --frames A-B | all: an animation along the manifest's camera path (docs/farm.md "Animation").
  std::string frames;
  float fov = 0.0f;
  bool quiet = false;
  // Every other render setting (--set, --settings, the manifest's "settings"; settings_args.h).
  SettingArgs settings;
  // Plan (farm and --local-only); plan.empty() = the classic single-process render.
  std::string plan;
  uint32_t maps = 1;
  uint32_t passes = 8;  // progressive
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
  double target_error = 0;  // progressive plan (or the unbiased path tracer): noise and bias
  int32_t priority = 0;
  std::string name;
  // pf submit --after JOB (repeatable): jobs it waits for (docs/farm.md "Job dependencies").
  std::vector<std::string> after;
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
};

// A scene manifest's "settings": spp (of a plain render, unless --spp) and the render settings
// (a.settings.manifest, applied under the command line's; settings_args.h). No-op for a geometry
// file. InputError if a value is malformed.
void ApplyManifestSettings(RenderArgs& a);

// Scene, camera, integrator, spp and the render settings (render and submit). With `all` false
// the options a person rarely needs are hidden from --help (`pf render --help-all` shows them).
void AddSceneOptions(CLI::App* app, RenderArgs& a, bool all);

// The settings given on the command line, checked before anything runs: CLI::ValidationError
// (exit 2) for an unknown or malformed setting, a broken rule or a setting the chosen integrator
// would ignore (an error rather than a warning: the image would not show what was asked for).
void CheckSettingArgs(const RenderArgs& a);

// --plan, --maps, --stride, --rounds, --tile, stop rule, --priority, --name.
void AddPlanOptions(CLI::App* app, RenderArgs& a, bool all);

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

// The render settings as the job's RenderSettings (auto values left auto).
void RenderSettingsFromArgs(const RenderArgs& a, photonfarm::v1::RenderSettings* out);

// Logs what each `auto` setting becomes for this scene, and why; returns the resolved settings.
JobRenderSettings ResolveAndLog(const JobRenderSettings& settings, const SceneDescription& scene);

std::string FormatVec(const Vec3& v);
std::string FormatVec(const Vec3d& v);

}  // namespace pf
