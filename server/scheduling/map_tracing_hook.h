#pragma once
// The scheduler's hook for photon maps traced once (docs/farm.md "Photon maps traced
// once"): work that comes before render tasks (pieces of maps to trace) and a gate that keeps a
// render task out of the queue until its map is built. Implemented by DistributedMaps
// (distributed_maps.h); a Scheduler without one behaves as before.
//
// The leases of pieces are the Scheduler's (lease_table.h: one table, one issuer, one path for
// ExtendLease, FailTask, ReturnLease, uploads and expiry); the hook keeps what is map-specific —
// which piece is next, its attempts and state (map_states.h), the pieces on disk, their checks and
// the assembly — and is told by the Scheduler what became of a piece's lease.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/plan/task_plan.h"

namespace pf::server {

class Job;
struct Lease;
struct LeaseRequest;

// A lease on photons [photon_begin, photon_end) of a map (Task.trace_chunk).
struct TraceChunkLease {
  std::string map_key;
  uint64_t photon_begin = 0, photon_end = 0;
  uint32_t chunk_index = 0, chunk_count = 0;
};

// What became of a piece's lease, told by the Scheduler outside its lock (a failure is reported
// back to the Scheduler's worker health, and may release render tasks).
struct PieceLeaseEnd {
  enum class Why { kFailed, kExpired };
  Why why = Why::kFailed;
  std::string map_key;
  uint32_t piece = 0;
  std::string lease_id, worker_id;
  std::string reason;  // kFailed: the worker's
};

class MapTracingHook {
 public:
  virtual ~MapTracingHook() = default;
  // Called under the scheduler's lock: they must not call back into the Scheduler and must not do
  // O(photons) work or I/O.
  // Whether `task` of `job` may be queued now (its map is built, or traced by its worker). If not,
  // the scheduler holds it back until Scheduler::ReleaseMap(job, map index).
  virtual bool RenderTaskReady(const Job& job, const TaskSpec& task) = 0;
  // A piece of a map to trace, as a lease with Lease::chunk set; served before render tasks.
  // Only of jobs `may_lease(job_id)` allows (worker health: not blocklisted for the job; null: any).
  // Its lease id comes from `issue` (the Scheduler's LeaseTable, which holds the deadline).
  using JobFilter = std::function<bool(const std::string& job_id)>;
  using IssuePieceLease = std::function<std::string(const std::string& job_id, const std::string& map_key,
                                                    uint32_t piece, uint32_t attempt)>;
  virtual std::optional<Lease> LeaseChunk(const LeaseRequest& request, const JobFilter& may_lease,
                                          const IssuePieceLease& issue) = 0;
  // Whether `lease_id` is still the lease of the piece: a piece may be stored, or its map left to
  // the workers or purged, without the Scheduler (its table entry is then dropped on its next use).
  virtual bool PieceLeaseCurrent(const std::string& map_key, uint32_t piece, const std::string& lease_id) = 0;
  // The jobs a piece of the map counts in (the map's job and every job waiting for it).
  virtual std::vector<std::string> JobsOfMap(const std::string& map_key) = 0;
  // The lease never reached its worker: the piece is queued again, its attempt not counted.
  virtual void PieceReturned(const std::string& map_key, uint32_t piece, const std::string& lease_id) = 0;

  // Called *outside* the scheduler's locks.
  // A piece's lease failed or ran out: queued again (attempt + 1), the failure reported to the
  // Scheduler (PieceAttemptFailed).
  virtual void PieceLeaseEnded(const PieceLeaseEnd& end) = 0;
  // A worker was convicted (docs/farm.md "Result verification"; it may delete files): every stored
  // map holding pieces it traced is deleted and traced again, without its pieces. Returns the ids
  // of the jobs whose render tasks used such a built map (the scheduler restarts the active ones).
  virtual std::vector<std::string> WorkerConvicted(const std::string& /*worker_id*/) { return {}; }
};

}  // namespace pf::server
