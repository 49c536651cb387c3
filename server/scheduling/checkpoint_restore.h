#pragma once
// A checkpoint's merged results put into a fresh job (server/store/checkpoint.h): the accumulator
// and exactly the tasks it holds, marked merged and stored. Recovery resumes a job from its own
// checkpoint this way; RequeueJob starts a new job from a finished job's (job_requeue.h).

#include <string>
#include <vector>

#include "common/plan/accumulator.h"
#include "server/jobs/job.h"
#include "server/store/records.h"

namespace pf::server {

// The tasks beyond the job's current ones that its plan creates from the results in `acc`
// (the hierarchical plan's localization tasks; none for static plans).
std::vector<TaskSpec> TasksCreatedFromResults(const Job& job, const Accumulator& acc);

// Applies `cp` (sealed as `seal`) to a job with nothing merged; false (job untouched, `problem`
// says why) if it does not fit the job: another job's id, image size or task list.
bool ApplyCheckpoint(const Checkpoint& cp, const CheckpointSeal& seal, Job& job, std::string* problem);

}  // namespace pf::server
