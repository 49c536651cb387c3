#pragma once
// The lease table of a Scheduler (server/scheduling/scheduler.h): the one table of every lease the
// coordinator hands out, whatever it names — a render task of a job, or a piece of a photon map to
// trace (docs/farm.md "Photon maps traced once"; distributed_maps.h). Each entry says its kind and
// what it names, and the Scheduler's one lease path (FindLiveLease: ExtendLease, FailTask,
// ReturnLease, CompleteTask, the upload of a piece and the expiry on Tick) dispatches by that kind,
// never by the form of the id.
//
// A lease id is the worker's proof that it holds the work, with the worker id it was leased to
// (checked on every use: docs/security.md, "Leases are bound to their worker"). Every id has one
// form, made here: the job, the task (or piece) and the attempt it names, and 128 random bits from
// the CSPRNG — so it cannot be guessed, and a restarted coordinator never hands out an id again.
//
// Deadlines and holders: a render task's live in its TaskRuntime (server/jobs/job.h: the scheduler
// reads them everywhere); a map piece has no TaskRuntime, so its entry holds them. This table maps
// ids to what they name and finds the ones that ran out. Not thread-safe (the Scheduler's lock
// guards it).

#include <cstdint>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "server/jobs/job.h"

namespace pf::server {

enum class LeaseKind { kRenderTask, kMapPiece };

class LeaseTable {
 public:
  struct Entry {
    LeaseKind kind = LeaseKind::kRenderTask;
    Job* job = nullptr;    // kRenderTask: the task's job
    uint64_t task_id = 0;  // kRenderTask: the task; kMapPiece: the piece's index in its map
    // kMapPiece: the map (its key, distributed_maps.h), the holder and the deadline.
    std::string map_key;
    std::string worker_id;
    double deadline = 0;
  };

  // A fresh lease id for the task's current attempt, registered in the table.
  std::string Issue(Job& job, uint64_t task_id, uint32_t attempt);
  // A fresh lease id for attempt `attempt` of piece `piece` of the map `map_key` (whose tracing
  // `job_id` asked for), held by `worker_id` until `deadline`, registered in the table.
  std::string IssuePiece(const std::string& job_id, const std::string& map_key, uint32_t piece,
                         uint32_t attempt, const std::string& worker_id, double deadline);
  // A fresh id of the same form, not registered (a verification's lease: result_verification.h —
  // the worker cannot tell it from a task's).
  static std::string MakeId(std::string_view job_id, uint64_t task_id, uint32_t attempt);
  // nullptr if unknown (never issued, or already erased).
  Entry* Find(const std::string& lease_id);
  void Erase(const std::string& lease_id) { leases_.erase(lease_id); }

  // Lease ids whose deadline is ≤ now (of either kind).
  std::vector<std::string> Expired(double now) const;
  // Σ reported progress (0..1) × work (Job::task_work) of the job's leased tasks (for the ETA).
  double ProgressOf(const Job& job) const;

 private:
  std::unordered_map<std::string, Entry> leases_;
};

}  // namespace pf::server
