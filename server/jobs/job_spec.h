#pragma once
// JobSpec (wire) → JobConfig (core types): the one validation of a submitted job, run before
// anything is stored (docs/design.md, G4). Recovery runs it again on the stored, normalised spec,
// so a resumed job is configured exactly as it was accepted.
//
// Rules, in order (the first violation is reported, its message starting with the field path):
//   spec.name            ≤ 256 bytes                                        INVALID_ARGUMENT
//   spec.scene_hash      64 lowercase hex digits                            INVALID_ARGUMENT
//                        known to the coordinator (UploadScene)             NOT_FOUND
//   spec.camera          unset, or only width/height set: the scene's camera (its manifest's
//                        first camera, else DefaultCamera), at width × height when both > 0;
//                        otherwise a full camera (eye ≠ look_at, up not parallel, vfov in
//                        (0, 180), width and height > 0)                    INVALID_ARGUMENT
//                        over kMaxImageSide / kMaxImagePixels (proto/convert.h)  RESOURCE_EXHAUSTED
//   spec.settings        proto/convert.h SettingsFromProto (photons, k ≥ 1 and their limits);
//                        then the `auto`s the scene decides are resolved (JobRenderSettings::Resolved)
//   spec.plan            auto_plan: replaced by the chosen plan (ResolveAutoPlan), then as that;
//                        proto/convert.h PlanFromProto, then ValidatePlan (S² ≤ pixels, …)
//                        more than limits::kMaxTasksPerJob tasks, or a task of more than
//                        kMaxPixelsPerTask pixels                           RESOURCE_EXHAUSTED
//   spec.animation       1 ≤ cameras ≤ limits::kMaxFrames, each a full camera at the job's
//                        resolution (width/height 0 or equal); spec.camera's view, if given, is
//                        cameras[0]'s; the plan not auto_plan and one FramesPlanProblem allows;
//                        width × height × frames ≤ kMaxImagePixels           INVALID_ARGUMENT /
//                                                                           RESOURCE_EXHAUSTED
//   spec.after           ≤ limits::kMaxDependencies ids, each non-empty, ≤ kMaxIdBytes, distinct
//                        (that each names a known job is the admission's check)  INVALID_ARGUMENT
//   spec.stop            time_budget_seconds, target_noise_rms, target_error_rms finite and ≥ 0;
//                        the targets as StopTargetsProblem allows them (common/plan/stop_targets.h)
//
// Why kMaxPixelsPerTask: a task's result carries 3 floats per pixel in one CompleteTask message,
// which must fit the coordinator's 64 MiB receive limit (4 Mi pixels = 48 MiB). Use tiles for
// larger images.

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "common/plan/stop_targets.h"
#include "common/plan/task_executor.h"
#include "common/plan/task_plan.h"
#include "common/scene/scene.h"
#include "photonfarm/v1/farm.pb.h"
#include "proto/limits.h"
#include "server/store/scene_catalog.h"

namespace pf::server {

inline constexpr uint64_t kMaxPixelsPerTask = uint64_t(4) << 20;
inline constexpr size_t kMaxJobNameBytes = limits::kMaxJobNameBytes;

struct StopRule {
  uint32_t max_rounds = 0;         // 0 = all planned rounds
  double time_budget_seconds = 0;  // 0 = none
  double target_noise_rms = 0;     // 0 = none
  double target_error_rms = 0;     // 0 = none; the progressive plan's (common/plan/stop_targets.h)
  StopTargets targets() const {
    return {.target_noise_rms = target_noise_rms, .target_error_rms = target_error_rms};
  }
};

// A validated job.
struct JobConfig {
  std::string name;
  std::string scene_hash;
  std::string scene_entry;
  CameraSpec camera;
  JobRenderSettings settings;
  PlanSpec plan;
  uint64_t seed = 0;
  StopRule stop;
  int32_t priority = 0;
  // The jobs it waits for (JobSpec.after; docs/farm.md "Job dependencies"), as stored: whole ids
  // once admitted (CoordinatorOperations::AdmitJob resolves prefixes).
  std::vector<std::string> after;
  // The spec as accepted, with the camera, an auto plan and the scene's `auto` settings resolved:
  // echoed in JobStatus.spec and stored.
  photonfarm::v1::JobSpec spec;
  // The `auto` settings resolved at this validation, with their reasons (logged at submission;
  // empty when the spec was resolved already, as a recovered job's is).
  std::vector<AutoChoice> auto_choices;
  // The result bound (docs/security.md, "Results"): a task's per-pixel channel sum above
  // samples × this is implausible. limits::kResultRadianceFactor × the scene's brightest
  // emitter; infinite when the scene's emission is unknown (a database from before the bound).
  double max_sample_radiance = std::numeric_limits<double>::infinity();

  // An animation (spec.animation; common/plan/frame_tasks.h): its frames' cameras, frames[0] =
  // camera, and the number of its first frame. Empty for a still image.
  std::vector<CameraSpec> frames;
  uint32_t first_frame = 0;

  // Rounds that are scheduled: min(plan rounds, stop.max_rounds) (max_rounds 0 = all).
  uint32_t ScheduledRounds() const;
  uint32_t frame_count() const { return frames.empty() ? 1u : uint32_t(frames.size()); }
  // The job's image — its frames stacked top to bottom — is camera.width × image_height().
  int image_height() const { return camera.height * int(frame_count()); }
  // The camera that renders `task`: its frame's.
  const CameraSpec& CameraOf(const TaskSpec& task) const {
    return frames.empty() ? camera : frames.at(task.frame);
  }
};

// Throws InputError / LimitError / NotFoundError naming the field (rules above). A plan of
// `auto_plan` is resolved first (proto/convert.h ResolveAutoPlan, for `live_workers` workers when
// it does not say how many): the returned config and its spec hold the chosen plan.
JobConfig ValidateJobSpec(const photonfarm::v1::JobSpec& spec, const SceneCatalog& scenes,
                          uint32_t live_workers = 1);

// The tasks a job schedules: ExpandFrames (ExpandPlan for a still image) restricted to rounds <
// ScheduledRounds(). Task ids are the expansion's, so they are equal to the index in the result.
std::vector<TaskSpec> ScheduledTasks(const JobConfig& config);
// ScheduledTasks(config).size() without expanding the plan: what the budgets (server/rpc/budgets.h)
// and the recovery of a finished job count.
uint64_t ScheduledTaskCount(const JobConfig& config);

}  // namespace pf::server
