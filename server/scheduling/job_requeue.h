#pragma once
// Requeueing a finished job (docs/farm.md "Requeueing a job"): a new job with the finished job's
// spec — the plan made longer and the stop rule replaced if asked — that starts from the finished
// job's merged results wherever the new plan has the same tasks. Task ids are the plan's
// expansion and a longer progressive, multiple-maps or skipping plan keeps every task of the
// shorter one (common/plan/task_plan.h: pass-, map- and round-major), so the new job renders only
// what is missing — a failed or cancelled job's rest, further passes — and its image is the one
// a job submitted with the new spec renders, bit for bit (the merge is a fixed-point sum, which
// does not depend on which job merged a task).
//
// Durable in the order recovery reads it: the carried results are written as the new job's own
// checkpoint first (an orphan if the coordinator dies now: recovery sets it aside; removed if the
// insert below fails), then its row and the carried tasks' DONE rows in one insert, and only then
// is the job scheduled (recovery resumes an unfinished job from its checkpoint file, as ever). The finished
// job is not touched; deleting it later takes nothing from the new one.

#include <cstdint>
#include <filesystem>
#include <string>

#include "photonfarm/v1/farm.pb.h"
#include "server/jobs/job_spec.h"
#include "server/scheduling/scheduler.h"
#include "server/store/job_store.h"

namespace pf::server {

// The new job's spec: `source`'s stored spec with the plan's length set to `extend_to` (0 = the
// same) and its stop rule replaced by `stop` when given; requeued_from names the source, and it
// waits for nothing (spec.after: the source ran, so what it waited for has ended). Throws
// InputError naming the field: extend_to below the plan's length, for a plan that has none
// (maps in turn, hierarchical), or for multiple maps ending in tail tiles (the last map's tasks
// differ from an inner map's, so the plans would share no last map).
photonfarm::v1::JobSpec RequeuedSpec(const Scheduler::FinishedJob& source, uint32_t extend_to,
                                     const photonfarm::v1::StopRule* stop);

struct RequeuedJob {
  std::string job_id;
  uint64_t tasks_carried = 0;
};

// Admits `config` (RequeuedSpec validated again, ValidateJobSpec) as a new job carrying
// `source`'s merged results (see above). Throws PreconditionError when there is nothing left to
// render (every task of the new plan merged already), UnavailableError while the source's final
// checkpoint is not written yet (pf requeue retries), and what the store throws (nothing is then
// scheduled, and the new checkpoint file is removed). Carries nothing — the new
// job renders everything, with a warning logged — when the source's checkpoint fails its seal or
// was rendered by another build (docs/farm.md, Upgrades: an image never mixes builds).
RequeuedJob RequeueValidatedJob(Scheduler& scheduler, JobStore& db,
                                const std::filesystem::path& checkpoint_dir,
                                const Scheduler::FinishedJob& source, JobConfig config,
                                const std::string& client);

}  // namespace pf::server
