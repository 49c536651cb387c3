#pragma once
// Admission of a validated job, the one step SubmitJob takes into scheduling (docs/design.md, S4:
// the RPC layer validates at the edge and hands over; it neither builds rows nor calls the
// scheduler twice). In order: the job gets its id and tasks (Scheduler::PrepareJob), its row is
// stored — durable before the client hears the id (docs/farm.md, "SQLite schema"; no task rows:
// a task without a row is QUEUED with no attempts, which recovery assumes) — and only then is it
// handed to the scheduler (Scheduler::AddJob). Runs on a background thread: PrepareJob expands the
// plan and the insert waits for SQLite.

#include <string>

#include "server/jobs/job_spec.h"
#include "server/scheduling/scheduler.h"
#include "server/store/job_store.h"

namespace pf::server {

// The row of a job just prepared (Scheduler::PrepareJob): QUEUED, its spec as accepted.
JobRow QueuedJobRow(const Job& job);

// Returns the new job's id. Throws what the store throws (the job is then not scheduled).
std::string SubmitValidatedJob(Scheduler& scheduler, JobStore& db, JobConfig config,
                               const std::string& client);

}  // namespace pf::server
