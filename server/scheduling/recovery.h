#pragma once
// Coordinator start-up after a stop or a crash (docs/design.md, G3): every job in the database is
// rebuilt from its stored, normalised spec (validated again, expanded again: the plan is a pure
// function) and handed to the scheduler.
//
//  - Unfinished jobs: the checkpoint file and then the result journal decide which tasks are
//    merged (the checkpoint's accumulator holds exactly its listed tasks; journal entries of tasks
//    not in it are merged again, order does not matter). Every other task — queued, leased to a
//    worker before the crash, or marked done in the database but in neither file — is queued
//    again. Attempt and failure
//    counts come from the database (a coordinator crash does not count as a failed attempt).
//    A corrupt checkpoint is logged and the job restarts from zero merges (never double counts).
//    A job whose spec no longer validates (e.g. its scene folder was deleted) is marked FAILED.
//    A DONE task row names a stored result (persister.h, D2): one the files do not hold is a lost
//    acknowledged result, logged as DATA LOSS and re-run.
//  - Finished jobs are listed with their final state; their image is read from the checkpoint
//    file when asked for (not held in memory), and only if the file carries the seal stored in
//    the job's row. A SUCCEEDED job whose file does not is rendered again from zero (same spec,
//    same seed: the same image, unless a time budget cut it); a failed or cancelled one answers
//    DATA_LOSS for its image.

#include <cstdint>
#include <filesystem>

#include "server/clock.h"
#include "server/jobs/job_spec.h"
#include "server/scheduling/scheduler.h"
#include "server/store/job_store.h"

namespace pf::server {

struct RecoveryReport {
  uint64_t jobs_resumed = 0;
  uint64_t jobs_finished = 0;
  uint64_t jobs_failed = 0;   // could not be resumed
  uint64_t tasks_merged = 0;  // restored from checkpoints and journals (not re-run)
  uint64_t tasks_from_journal = 0;
  uint64_t tasks_requeued = 0;
  uint64_t journals_damaged = 0;  // damage before the end: acknowledged results lost (re-run)
  uint64_t jobs_reexpanded = 0;   // stored under another plan expansion version: re-run from zero
  uint64_t jobs_other_build = 0;  // submitted under another build (JobSpec.plan.build): re-run from zero
  // DATA LOSS (each logged as an error; docs/farm.md "Durability"):
  uint64_t acknowledged_lost = 0;  // DONE rows whose result neither checkpoint nor journal holds (re-run)
  uint64_t jobs_rerendered = 0;    // SUCCEEDED jobs whose final image failed its seal: rendered again
  uint64_t images_lost = 0;        // failed or cancelled jobs whose image failed its seal: not served
};

// An unfinished job submitted under another coordinator build than scheduler.options().build has
// its merged results set aside and its tasks re-run — unless `keep_other_builds`
// (--allow-mixed-versions), which resumes it, its image then mixing the builds. Either way it is
// stamped with this build from then on (docs/farm.md, Upgrades).
RecoveryReport RecoverJobs(JobStore& db, const SceneCatalog& scenes,
                           const std::filesystem::path& checkpoint_dir, Scheduler& scheduler,
                           const Clock& clock, bool keep_other_builds = false);

}  // namespace pf::server
