#pragma once
// The stop rules of a job (JobSpec.stop), as decisions; the Scheduler (scheduler.h) acts on them.
//
//  max_rounds     rounds ≥ max are never scheduled (JobConfig::ScheduledRounds, server/jobs/).
//  time budget    once the job has been RUNNING that long nothing new is leased, the queued tasks
//                 are cancelled, leased ones may finish, and the job SUCCEEDS with what was merged.
//  target noise   after a merge, once every pixel has ≥ 2 independent maps (two full rounds, or
//                 two complete maps) and Accumulator::EstimatedNoiseRms() ≤ target, the job
//                 SUCCEEDS and its remaining tasks are cancelled. The estimate is an O(pixels)
//                 pass, so it is refreshed at most every noise_check_interval — except when no
//                 task is left to wait for.
//  target error   the same, with √(noise² + bias²) of the progressive plan (common/plan/
//                 stop_targets.h) once every pixel has kMinPassesForBias passes. A job that runs
//                 out of tasks (or time) first SUCCEEDS with its image and says which target it
//                 missed (JobStatus.target_missed).

#include "common/plan/stop_targets.h"
#include "server/jobs/job.h"

namespace pf::server {

// The job's time budget is set and used up (and the job is not already stopping).
bool TimeBudgetReached(const Job& job, double now);

// Whether the target-noise rule should estimate the noise now (see above).
bool NoiseTargetDue(const Job& job, double now, double check_interval);
// After Job::SetNoise: the estimate meets the target.
bool NoiseTargetMet(const Job& job);

}  // namespace pf::server
