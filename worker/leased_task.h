#pragma once
// A task as the pull loop holds it after LeaseTask: its fields read into core types, the context
// its log lines name it by, and how a step can end it before its result (docs/farm.md, "Worker").

#include <cstdint>
#include <string>
#include <utility>

#include "common/plan/task_plan.h"
#include "common/render/job_render_settings.h"
#include "common/scene/scene.h"
#include "photonfarm/v1/farm.pb.h"

namespace pf::worker {

// A render task's fields in core types.
struct ParsedTask {
  CameraSpec camera;
  JobRenderSettings settings;
  TaskSpec spec;
  uint64_t pixels = 0;  // in the task's subset
};

// Throws InputError naming the field of a task that cannot be read (a permanent failure). Leaves
// `pixels` 0: CountTaskPixels counts them once the task is known to be readable.
ParsedTask ParseTask(const photonfarm::v1::Task& task);
uint64_t CountTaskPixels(const ParsedTask& parsed);

// "job=J task=T attempt=A" (render tasks), "job=J map=M piece=I/N attempt=A" (map pieces): the
// e2e tests grep log lines by them.
std::string TaskContext(const photonfarm::v1::Task& task);
std::string PieceContext(const photonfarm::v1::Task& task);

// A step (the scene, the map) ended the task before its result: either it failed (the loop logs
// it and tells the coordinator, FailTask), or the coordinator is unreachable and the lease is left
// to expire (the loop backs off).
struct TaskEnd {
  static TaskEnd Failed(std::string reason, bool retryable) { return {false, std::move(reason), retryable}; }
  static TaskEnd Unreachable() { return {true, "", true}; }
  bool unreachable = false;
  std::string reason;  // of a failure
  bool retryable = true;
};

}  // namespace pf::worker
