#pragma once
// The lease table of a Scheduler (server/scheduling/scheduler.h): which lease id stands for which
// task of which job. A lease id is the worker's proof that it holds a task, with the worker id it
// was leased to (the Scheduler checks both: docs/security.md, "Leases are bound to their
// worker"), so it carries 128 random bits from the CSPRNG besides the job, task and attempt it
// names.
//
// Deadlines and attempts live in the task's TaskRuntime (server/jobs/job.h); this table only maps
// ids to tasks and finds the ones that ran out. Not thread-safe (the Scheduler's lock guards it).

#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "server/jobs/job.h"

namespace pf::server {

class LeaseTable {
 public:
  struct Entry {
    Job* job;
    uint64_t task_id;
  };

  // A fresh lease id for the task's current attempt, registered in the table.
  std::string Issue(Job& job, uint64_t task_id, uint32_t attempt);
  // A fresh id of the same form, not registered (a verification's lease: result_verification.h —
  // the worker cannot tell it from a task's).
  static std::string MakeId(const Job& job, uint64_t task_id, uint32_t attempt);
  // nullptr if unknown (never issued, or already erased).
  Entry* Find(const std::string& lease_id);
  void Erase(const std::string& lease_id) { leases_.erase(lease_id); }

  // Lease ids whose deadline is ≤ now.
  std::vector<std::string> Expired(double now) const;
  // Σ reported progress (0..1) × work (Job::task_work) of the job's leased tasks (for the ETA).
  double ProgressOf(const Job& job) const;

 private:
  std::unordered_map<std::string, Entry> leases_;
};

}  // namespace pf::server
