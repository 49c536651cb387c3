#pragma once
// The scheduler's hook for photon maps traced once (docs/farm.md "Photon maps traced
// once"): what is map-specific about the pieces of maps to trace, and a gate that keeps a render
// task out of the queue until its map is built. Implemented by DistributedMaps
// (distributed_maps.h); a Scheduler without one behaves as before.
//
// The queue and the leases of pieces are the Scheduler's: a piece waits in its one TaskQueue
// (task_queue.h: pieces before render tasks, oldest map first) and is leased through its one
// LeaseTable (lease_table.h: one issuer, one path for ExtendLease, FailTask, ReturnLease, uploads
// and expiry). The hook keeps what a piece is — its state (map_states.h), attempts and failed
// workers, the pieces on disk, their checks and the assembly — and answers each event with a
// MapUpdate: which maps' queued pieces changed, which attempts failed, which maps are ready. The
// Scheduler applies it under its lock (ApplyMapUpdate); the hook never calls the Scheduler back
// from a call of the Scheduler.

#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "common/plan/task_plan.h"
#include "server/scheduling/task_queue.h"

namespace pf::server {

class Job;
struct Lease;

// A lease on photons [photon_begin, photon_end) of a map (Task.trace_chunk).
struct TraceChunkLease {
  std::string map_key;
  uint64_t photon_begin = 0, photon_end = 0;
  uint32_t chunk_index = 0, chunk_count = 0;
};

// What became of a piece's lease, told by the Scheduler under its lock.
struct PieceLeaseEnd {
  enum class Why { kFailed, kExpired };
  Why why = Why::kFailed;
  std::string map_key;
  uint32_t piece = 0;
  std::string lease_id, worker_id;
  std::string reason;  // kFailed: the worker's
};

// A failed piece attempt (`kind`: piece-failed, piece-expired, piece-refused): it counts against
// its worker in the job like a render task's (worker health: blocklist, quarantine, no worker left).
struct PieceFailure {
  std::string job_id, worker_id, kind, reason;
  uint32_t piece = 0, attempt = 0;
};

// What a map event changed, for the Scheduler to apply under its lock (in this order).
struct MapUpdate {
  // Maps whose queued pieces changed: the Scheduler sets their pieces in its queue from
  // MapTracingHook::QueuedPiecesOf (the map's state is the truth, so an update applied late or
  // twice leaves the queue right).
  std::set<std::string> maps = {};
  // Failed attempts, each counted against its worker when applied: an update is applied once (a
  // second application would count the failures again; `maps` and `release` would be harmless).
  std::vector<PieceFailure> failures = {};
  // (job, map index): the map is built or left to the workers; its held render tasks join the queue.
  std::vector<std::pair<std::string, uint64_t>> release = {};
  bool empty() const { return maps.empty() && failures.empty() && release.empty(); }
};

class MapTracingHook {
 public:
  virtual ~MapTracingHook() = default;
  // Called under the scheduler's lock: they must not call back into the Scheduler and must not do
  // O(photons) work or I/O.
  // Whether `task` of `job` may be queued now (its map is built, or traced by its worker). If not,
  // the scheduler holds it back until the map is released (MapUpdate::release); a map created for
  // it adds its pieces to `update`.
  virtual bool RenderTaskReady(const Job& job, const TaskSpec& task, MapUpdate& update) = 0;
  // The map's creation order and its queued pieces (none unless it is tracing).
  struct QueuedPieces {
    uint64_t map_seq = 0;
    std::vector<uint32_t> pieces;
  };
  virtual QueuedPieces QueuedPiecesOf(const std::string& map_key) = 0;
  // The piece the queue chose, leased to `worker_id`, as a lease with Lease::chunk set; its lease
  // id comes from `issue` (the Scheduler's LeaseTable, which holds the deadline). nullopt if the
  // piece is not queued in its map.
  using IssuePieceLease = std::function<std::string(const std::string& job_id, const std::string& map_key,
                                                    uint32_t piece, uint32_t attempt)>;
  virtual std::optional<Lease> LeasePiece(const TaskQueue::Piece& piece, const std::string& worker_id,
                                          const IssuePieceLease& issue) = 0;
  // Whether `lease_id` is still the lease of the piece: a piece may be stored, or its map left to
  // the workers or purged, without the Scheduler (its table entry is then dropped on its next use).
  virtual bool PieceLeaseCurrent(const std::string& map_key, uint32_t piece, const std::string& lease_id) = 0;
  // The jobs a piece of the map counts in (the map's job and every job waiting for it).
  virtual std::vector<std::string> JobsOfMap(const std::string& map_key) = 0;
  // The lease never reached its worker: the piece is queued again, its attempt not counted.
  virtual MapUpdate PieceReturned(const std::string& map_key, uint32_t piece,
                                  const std::string& lease_id) = 0;
  // A piece's lease failed or ran out: queued again (attempt + 1), the failure in the update (or,
  // after failures on too many workers, the map left to the workers: its render tasks released).
  virtual MapUpdate PieceLeaseEnded(const PieceLeaseEnd& end) = 0;

  // Called *outside* the scheduler's locks.
  // A worker was convicted (docs/farm.md "Result verification"; it may delete files): every stored
  // map holding pieces it traced is deleted and traced again, without its pieces. Returns the ids
  // of the jobs whose render tasks used such a built map (the scheduler restarts the active ones).
  virtual std::vector<std::string> WorkerConvicted(const std::string& /*worker_id*/) { return {}; }
};

}  // namespace pf::server
