#include "server/jobs/job_spec.h"

#include "common/plan/stop_targets.h"
#include "common/render/integrator_factory.h"

#include "proto/limits.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <cmath>

#include "common/core/error.h"
#include "common/plan/frame_tasks.h"
#include "common/plan/plan_choice.h"
#include "common/render/progressive_radius.h"
#include "common/render/render_settings_rules.h"
#include "proto/convert.h"
#include "server/errors.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

bool IsZero(const v1::Vec3& v) {
  return v.x() == 0 && v.y() == 0 && v.z() == 0;
}

// "Only width/height set": the client asks for the scene's camera (at that resolution).
bool WantsSceneCamera(const v1::JobSpec& spec) {
  if (!spec.has_camera()) return true;
  const v1::Camera& c = spec.camera();
  return IsZero(c.eye()) && IsZero(c.look_at()) && IsZero(c.up()) && c.vfov_degrees() == 0;
}

CameraSpec ResolveCamera(const v1::JobSpec& spec, const SceneInfo& scene) {
  if (!WantsSceneCamera(spec)) return CameraFromProto(spec.camera(), "spec.camera");
  v1::Camera c;
  CameraToProto(scene.camera, &c);
  const uint32_t w = spec.camera().width(), h = spec.camera().height();
  if ((w == 0) != (h == 0))
    throw InputError("spec.camera.width/height: set both (> 0) or neither (the scene camera's resolution)");
  if (w > 0) {
    c.set_width(w);
    c.set_height(h);
  }
  CameraSpec cam = CameraFromProto(c, "spec.camera");
  cam.name = scene.camera.name;
  return cam;
}

// spec.animation → job->frames (rules in job_spec.h), after job->camera is resolved.
void ResolveFrames(const v1::JobSpec& spec, JobConfig* job) {
  const v1::Animation& a = spec.animation();
  if (a.cameras_size() == 0) throw InputError("spec.animation.cameras: empty (one camera per frame)");
  if (size_t(a.cameras_size()) > limits::kMaxFrames)
    throw LimitError("spec.animation.cameras: " + std::to_string(a.cameras_size()) +
                     " frames exceed the limit of " + std::to_string(limits::kMaxFrames) +
                     " per job; split the frame range into several jobs");
  const uint64_t pixels =
      uint64_t(job->camera.width) * uint64_t(job->camera.height) * uint64_t(a.cameras_size());
  if (pixels > kMaxImagePixels)
    throw LimitError("spec.animation.cameras: " + std::to_string(a.cameras_size()) + " frames of " +
                     std::to_string(job->camera.width) + "x" + std::to_string(job->camera.height) + " are " +
                     std::to_string(pixels) + " pixels, over the limit of " +
                     std::to_string(kMaxImagePixels) +
                     " per job (the frames share one image); split the frame range into several jobs");
  if (uint64_t(a.first_frame()) + uint64_t(a.cameras_size()) > uint64_t(std::numeric_limits<uint32_t>::max()))
    throw InputError("spec.animation.first_frame: the last frame's number must fit 32 bits");
  for (int i = 0; i < a.cameras_size(); ++i) {
    const std::string field = "spec.animation.cameras[" + std::to_string(i) + "]";
    v1::Camera c = a.cameras(i);
    if ((c.width() != 0 || c.height() != 0) &&
        (int(c.width()) != job->camera.width || int(c.height()) != job->camera.height))
      throw InputError(field + ".width/height: " + std::to_string(c.width()) + "x" +
                       std::to_string(c.height()) + " differs from the job's " +
                       std::to_string(job->camera.width) + "x" + std::to_string(job->camera.height) +
                       " (set 0: every frame has the job's resolution)");
    c.set_width(uint32_t(job->camera.width));
    c.set_height(uint32_t(job->camera.height));
    CameraSpec cam = CameraFromProto(c, field);
    cam.name = "frame " + std::to_string(uint64_t(a.first_frame()) + uint64_t(i));
    job->frames.push_back(std::move(cam));
  }
  // spec.camera names the resolution; a view in it that is not the first frame's would be ignored.
  if (!WantsSceneCamera(spec)) {
    const CameraSpec& f = job->frames.front();
    const CameraSpec& c = job->camera;
    if (c.eye != f.eye || c.look_at != f.look_at || c.up != f.up || c.vfov_degrees != f.vfov_degrees)
      throw InputError(
          "spec.camera: its view differs from spec.animation.cameras[0]'s; with an animation set only its "
          "width/height, or the first frame's camera");
  }
  job->camera = job->frames.front();
  job->first_frame = a.first_frame();
}

void RequireFiniteNonNegative(double v, const std::string& field) {
  if (!std::isfinite(v) || v < 0) throw InputError(field + ": must be a finite number >= 0");
}

// ValidatePlan names fields relative to the job ("plan.skipping.stride", "camera: ..."); the
// wire names them relative to the request.
[[noreturn]] void RethrowUnderSpec(const InputError& e) {
  const std::string msg = e.what();
  if (msg.rfind("plan", 0) == 0 || msg.rfind("camera", 0) == 0) throw InputError("spec." + msg);
  throw InputError(msg);
}

uint64_t MaxPixelsPerTask(const PlanSpec& plan, int width, int height) {
  const uint64_t pixels = uint64_t(width) * uint64_t(height);
  if (plan.kind == PlanKind::kSkipping) {
    const uint64_t s2 = uint64_t(plan.stride) * plan.stride;
    return (pixels + s2 - 1) / s2;
  }
  if (plan.tile_size == 0) return pixels;
  // A band's points plus their parents, which lie on at most two other rows per point row.
  if (plan.kind == PlanKind::kHierarchical)
    return uint64_t(width) * std::min<uint64_t>(uint64_t(height), 3 * uint64_t(plan.tile_size));
  return uint64_t(std::min<uint64_t>(plan.tile_size, uint64_t(width))) *
         std::min<uint64_t>(plan.tile_size, uint64_t(height));
}

std::string PlanField(const PlanSpec& plan) {
  switch (plan.kind) {
    case PlanKind::kMultipleMaps:
      return "spec.plan.multiple_maps";
    case PlanKind::kMapsInTurn:
      return "spec.plan.maps_in_turn";
    case PlanKind::kSkipping:
      return "spec.plan.skipping";
    case PlanKind::kHierarchical:
      return "spec.plan.hierarchical";
    case PlanKind::kProgressive:
      return "spec.plan.progressive";
  }
  return "spec.plan";
}

}  // namespace

uint32_t JobConfig::ScheduledRounds() const {
  const uint32_t planned = CountRounds(plan);
  return stop.max_rounds == 0 ? planned : std::min(planned, stop.max_rounds);
}

JobConfig ValidateJobSpec(const v1::JobSpec& spec, const SceneCatalog& scenes, uint32_t live_workers) {
  JobConfig job;
  limits::CheckText(spec.name(), "spec.name", kMaxJobNameBytes);
  job.name = spec.name();
  if (size_t(spec.after_size()) > limits::kMaxDependencies)
    throw InputError("spec.after: more than " + std::to_string(limits::kMaxDependencies) + " jobs");
  for (int i = 0; i < spec.after_size(); ++i) {
    const std::string field = "spec.after[" + std::to_string(i) + "]";
    if (spec.after(i).empty()) throw InputError(field + ": empty (a job id or a unique prefix of one)");
    limits::CheckText(spec.after(i), field.c_str(), limits::kMaxIdBytes);
    if (std::find(job.after.begin(), job.after.end(), spec.after(i)) != job.after.end())
      throw InputError(field + ": " + limits::Quote(spec.after(i)) + " is named twice");
    job.after.push_back(spec.after(i));
  }

  const std::string& hash = spec.scene_hash();
  if (hash.empty()) throw InputError("spec.scene_hash: required (the hash UploadScene returned)");
  if (hash.size() != 64 || !std::all_of(hash.begin(), hash.end(), [](char c) {
        return std::isdigit(static_cast<unsigned char>(c)) || (c >= 'a' && c <= 'f');
      }))
    throw InputError("spec.scene_hash: must be 64 lowercase hex digits (the hash UploadScene returned)");
  const std::optional<SceneInfo> scene = scenes.FindScene(hash);
  if (!scene)
    throw NotFoundError("spec.scene_hash: unknown scene " + limits::Quote(hash) +
                        " (upload it with UploadScene first)");
  // Stored by an older coordinator, which took a scene without light with a warning; every
  // worker would now refuse to load it (common/scene/scene_loader.h, a scene without light).
  if (scene->lights == 0)
    throw InputError(
        "spec.scene_hash: scene " + limits::Quote(hash) +
        " has no light (no emitting material and no manifest \"lights\"); add one and upload it again");
  job.scene_hash = hash;
  job.scene_entry = scene->entry;
  if (scene->max_emission >= 0) job.max_sample_radiance = limits::kResultRadianceFactor * scene->max_emission;

  job.camera = ResolveCamera(spec, *scene);
  if (spec.has_animation()) ResolveFrames(spec, &job);
  // From here on the spec as the job stores and echoes it: an `auto_plan` is replaced by the
  // chosen plan, so a resumed job keeps it and the image does not depend on the farm at the time
  // of a restart. Every rule below reads this spec once.
  job.spec = spec;
  CameraToProto(job.camera, job.spec.mutable_camera());
  for (int i = 0; i < job.spec.animation().cameras_size(); ++i)
    CameraToProto(job.frames[size_t(i)], job.spec.mutable_animation()->mutable_cameras(i));
  if (!job.frames.empty() && job.spec.plan().has_auto_plan())
    throw InputError(
        "spec.plan.auto_plan: not with spec.animation (auto may choose skipping, whose every task has its "
        "own "
        "map); give multiple_maps, maps_in_turn or progressive, whose maps every frame shares");
  if (job.spec.plan().has_auto_plan())
    ResolveAutoPlan(&job.spec, job.camera.width, job.camera.height, scene->caustic_paths,
                    std::max(1u, live_workers), kMapsCanBeShipped, "spec");
  const v1::JobSpec& accepted = job.spec;
  job.settings = SettingsFromProto(accepted.settings(), "spec.settings");
  // A setting without effect is logged, not refused: a stored or scripted job keeps working
  // (docs/settings.md, "Settings that do not apply"; pf refuses them on its command line).
  for (const UnusedSetting& u : UnusedSettings(job.settings, NonDefaultSettings(job.settings)))
    spdlog::warn("job {}: setting {} {}", limits::Quote(accepted.name()), u.name, u.reason);
  // Stored resolved: the `auto`s the scene decides are made concrete here, once, from what the
  // upload recorded of the scene (docs/farm.md, "Validation of a job"), so the stored and echoed
  // spec, the map key and every worker hold the same concrete settings. A scene recorded before
  // caustic_paths was (-1) keeps its `auto`s: each worker resolves them alike.
  if (scene->caustic_paths >= 0) {
    job.settings = job.settings.Resolved(
        SceneTraits{.caustic_paths = scene->caustic_paths == 1, .lights = int(scene->lights)},
        &job.auto_choices);
    if (!job.auto_choices.empty()) SettingsToProto(job.settings, job.spec.mutable_settings());
  }
  // What pf chose (its integrator), checked, then what was resolved here, so the stored job and
  // its images say why each `auto` became what it is (the header's auto.* keys).
  AutoChoicesFromProto(accepted.auto_settings(), "spec.auto_settings");
  if (size_t(accepted.auto_settings_size()) + job.auto_choices.size() > limits::kMaxAutoSettings)
    throw InputError("spec.auto_settings: more than " + std::to_string(limits::kMaxAutoSettings) +
                     " entries with the coordinator's own " + std::to_string(job.auto_choices.size()));
  for (const AutoChoice& c : job.auto_choices) AutoChoiceToProto(c, job.spec.add_auto_settings());
  job.plan = PlanFromProto(accepted.plan(), "spec.plan");
  // α is stored explicitly with every progressive photon-map job, its default included: the
  // default has changed (2/3, now 1/2), and a job must resume with the α it started with
  // (recovery.cpp reads a stored progressive job without it as stored when 2/3 was the default).
  if (job.plan.kind == PlanKind::kProgressive)
    WriteProgressiveAlpha(job.settings, job.spec.mutable_settings());
  if (job.plan.kind != PlanKind::kProgressive)
    for (const std::string& name : NonDefaultSettings(job.settings))
      if (name.starts_with(kProgressiveSettingPrefix))
        spdlog::warn("job {}: setting {} applies only to the progressive plan",
                     limits::Quote(accepted.name()), name);
  try {
    ValidatePlan(job.plan, job.camera.width, job.camera.height);
  } catch (const LimitError&) {
    throw;
  } catch (const InputError& e) {
    RethrowUnderSpec(e);
  }
  if (!job.frames.empty()) {
    if (const std::string problem = FramesPlanProblem(job.plan); !problem.empty())
      throw InputError(PlanField(job.plan) + ": not with spec.animation: " + problem);
    // Each frame's importons make its own importance map (§4.7): correct, but nothing is shared.
    if (job.settings.importance != ImportanceMode::kOff)
      spdlog::warn(
          "job {}: importance-driven maps depend on the camera: each of the {} frames traces its own",
          limits::Quote(accepted.name()), job.frames.size());
  }
  // The split hierarchy renders the photon-map shader's two parts apart (radiance_part.h).
  if (job.plan.kind == PlanKind::kHierarchical && job.plan.hierarchy_part == HierarchyPart::kIndirect)
    CheckRadiancePartsApart(job.settings, "spec.plan.hierarchical.part");
  const uint64_t tasks = CountFrameTasks(job.plan, job.camera.width, job.camera.height, job.frame_count());
  if (const std::string problem = limits::TaskCountProblem(tasks); !problem.empty())
    throw LimitError(problem);
  const uint64_t task_pixels = MaxPixelsPerTask(job.plan, job.camera.width, job.camera.height);
  if (task_pixels > kMaxPixelsPerTask)
    throw LimitError(PlanField(job.plan) + ": a task of " + std::to_string(task_pixels) +
                     " pixels exceeds the limit of " + std::to_string(kMaxPixelsPerTask) +
                     " pixels per task (a result must fit one 64 MiB message); " +
                     (job.plan.kind == PlanKind::kSkipping ? "use a larger stride" : "use tiles"));

  RequireFiniteNonNegative(accepted.stop().time_budget_seconds(), "spec.stop.time_budget_seconds");
  RequireFiniteNonNegative(accepted.stop().target_noise_rms(), "spec.stop.target_noise_rms");
  RequireFiniteNonNegative(accepted.stop().target_error_rms(), "spec.stop.target_error_rms");
  job.stop.max_rounds = accepted.stop().max_rounds();
  job.stop.time_budget_seconds = accepted.stop().time_budget_seconds();
  // As judged (stop_targets.h): the path tracer's target error is a target noise.
  const StopTargets targets =
      JudgedTargets({.target_noise_rms = accepted.stop().target_noise_rms(),
                     .target_error_rms = accepted.stop().target_error_rms()},
                    !Integrators().FindKind(job.settings.integrator).UsesPhotonMaps());
  job.stop.target_noise_rms = targets.target_noise_rms;
  job.stop.target_error_rms = targets.target_error_rms;
  if (const std::string problem = StopTargetsProblem(targets, job.plan, "spec.stop"); !problem.empty())
    throw InputError(problem);
  // The noise estimate compares independent maps per pixel; a hierarchical pixel's value mixes
  // its parents' maps with its own details, which that estimate does not model.
  if (job.plan.kind == PlanKind::kHierarchical && job.stop.max_rounds > 0)
    throw InputError(
        "spec.stop.max_rounds: the hierarchical plan has no rounds (its levels all belong to one image); use "
        "time_budget_seconds");

  job.seed = accepted.seed();
  job.priority = accepted.priority();
  return job;
}

std::vector<TaskSpec> ScheduledTasks(const JobConfig& config) {
  std::vector<TaskSpec> tasks =
      ExpandFrames(config.plan, config.camera.width, config.camera.height, config.seed, config.frame_count());
  // Rounds are skipping's; a hierarchical task's `round` is its level, all of which are scheduled.
  const uint32_t rounds = config.plan.kind == PlanKind::kHierarchical ? ~0u : config.ScheduledRounds();
  tasks.erase(
      std::remove_if(tasks.begin(), tasks.end(), [&](const TaskSpec& t) { return t.round >= rounds; }),
      tasks.end());
  for (size_t i = 0; i < tasks.size(); ++i)
    if (tasks[i].task_id != i)
      throw std::logic_error("ScheduledTasks: task ids are not a prefix of the plan");
  return tasks;
}

uint64_t ScheduledTaskCount(const JobConfig& config) {
  const PlanSpec& plan = config.plan;
  // Skipping expands round by round, stride² tasks each (task_plan.h); ScheduledTasks keeps the
  // rounds below ScheduledRounds. Every other plan schedules all of its static tasks.
  if (plan.kind == PlanKind::kSkipping) return uint64_t(config.ScheduledRounds()) * plan.stride * plan.stride;
  return CountFrameTasks(plan, config.camera.width, config.camera.height, config.frame_count());
}

}  // namespace pf::server
