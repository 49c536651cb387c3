#pragma once
// The queue of a Scheduler (server/scheduling/scheduler.h): the one queue of the work the
// coordinator hands out, of two kinds — render tasks of jobs, and pieces of photon maps to trace
// (docs/farm.md "Photon maps traced once"; distributed_maps.h) — and which item a worker gets.
//
// Map pieces are served before render tasks (a render task waits for its map, so the map's pieces
// come first; the Scheduler serves a queued verification, result_verification.h, between the two
// kinds): the oldest map first (its creation order, which a map traced again after a
// conviction keeps), then the lowest piece. A worker blocklisted for a job of a map is passed over
// that map (ChoosePiece's filter). A piece is named by its map's key and its index; what a piece is
// (its photons, attempts, state) stays with the map (map_states.h), which tells the Scheduler which
// maps' queued pieces changed and the Scheduler sets them here (SetMapPieces). A held job (below)
// holds back its render tasks only: pieces may serve several jobs, and are not held.
//
// Render tasks. Jobs are served by priority (higher first), then submission order. Within the
// chosen job a worker gets the lowest queued task id — unless it reported cached photon maps and a
// queued task of that job uses one of them: then the lowest such task (map affinity; tiles of one
// map are adjacent in the plan). Affinity never crosses jobs: a map seed means a map only together
// with the job's scene and settings.
//
// A worker may have to pass some jobs or tasks by (worker health, worker_health.h: blocklisted for
// the job; a retry left to another worker): the Scheduler walks the jobs in order (NextJob) and
// passes Choose what to avoid.
//
// Only bookkeeping: task and job states are the Scheduler's, piece states the map's. Not thread-safe (the
// Scheduler's lock guards it).

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <unordered_map>

#include "server/jobs/job.h"

namespace pf::server {

class TaskQueue {
 public:
  struct Pick {
    uint64_t task_id = 0;
    bool map_cached = false;  // chosen by map affinity
  };
  // A job's place in the order: (−priority, submission sequence).
  using Position = std::pair<int64_t, uint64_t>;
  using Avoid = std::function<bool(uint64_t task_id)>;

  void Push(Job& job, uint64_t task_id);
  // No-op if the task is not queued.
  void Remove(Job& job, uint64_t task_id);
  // A held job keeps its queued tasks but is never served (a job whose results cannot be stored,
  // docs/farm.md "Durability"; one restarted from nothing, until its restart is stored), until
  // Unhold. Both idempotent.
  void Hold(const Job& job);
  bool Unhold(Job& job);  // true if it was held
  // A deleted job (pf delete): nothing of it stays queued or held.
  void Forget(const Job& job);

  // Nothing to serve: no render task of a job that is not held, and no map piece.
  bool empty() const { return ready_.empty() && pieces_.empty(); }
  // The first job with queued tasks after `after` in the order (from the first if nullopt);
  // nullptr if none.
  Job* NextJob(const std::optional<Position>& after) const;
  static Position PositionOf(const Job& job);
  // The task of `job` a worker with these cached map seeds gets (not removed), passing by the
  // tasks `avoid` names; nullopt if it avoids them all. Requires queued tasks.
  std::optional<Pick> Choose(const Job& job, std::span<const uint64_t> cached_map_seeds,
                             const Avoid& avoid = nullptr) const;

  // --- Map pieces ---
  struct Piece {
    std::string map_key;
    uint64_t map_seq = 0;  // the map's creation order
    uint32_t index = 0;
  };
  using MapFilter = std::function<bool(const std::string& map_key)>;
  // The queued pieces of the map become `indices` (none: the map leaves the queue).
  void SetMapPieces(const std::string& map_key, uint64_t map_seq, std::span<const uint32_t> indices);
  // No-op if the piece is not queued.
  void RemovePiece(uint64_t map_seq, uint32_t index);
  bool has_pieces() const { return !pieces_.empty(); }
  size_t queued_pieces() const;
  // The piece a worker gets (not removed): the lowest of the oldest map `may_lease` allows (null:
  // any); nullopt if none.
  std::optional<Piece> ChoosePiece(const MapFilter& may_lease = nullptr) const;

 private:
  struct JobQueue {
    std::set<uint64_t> ids;
    std::unordered_map<uint64_t, std::set<uint64_t>> by_seed;
  };
  std::unordered_map<const Job*, JobQueue> queues_;
  std::map<Position, Job*> ready_;  // jobs with queued tasks, not held
  std::set<const Job*> held_;
  struct MapPieces {
    std::string key;
    std::set<uint32_t> indices;
  };
  std::map<uint64_t, MapPieces> pieces_;  // maps with queued pieces, by creation order
};

}  // namespace pf::server
