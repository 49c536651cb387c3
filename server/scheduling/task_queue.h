#pragma once
// The queue of a Scheduler (server/scheduling/scheduler.h): which queued task a worker gets.
//
// Jobs are served by priority (higher first), then submission order. Within the chosen job a
// worker gets the lowest queued task id — unless it reported cached photon maps and a queued
// task of that job uses one of them: then the lowest such task (map affinity; tiles of one map
// are adjacent in the plan). Affinity never crosses jobs: a map seed means a map only together
// with the job's scene and settings.
//
// A worker may have to pass some jobs or tasks by (worker health, worker_health.h: blocklisted for
// the job; a retry left to another worker): the Scheduler walks the jobs in order (NextJob) and
// passes Choose what to avoid.
//
// Only bookkeeping: task and job states are the Scheduler's. Not thread-safe (the Scheduler's
// lock guards it).

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <span>
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

  bool empty() const { return ready_.empty(); }
  // The first job with queued tasks after `after` in the order (from the first if nullopt);
  // nullptr if none.
  Job* NextJob(const std::optional<Position>& after) const;
  static Position PositionOf(const Job& job);
  // The task of `job` a worker with these cached map seeds gets (not removed), passing by the
  // tasks `avoid` names; nullopt if it avoids them all. Requires queued tasks.
  std::optional<Pick> Choose(const Job& job, std::span<const uint64_t> cached_map_seeds,
                             const Avoid& avoid = nullptr) const;

 private:
  struct JobQueue {
    std::set<uint64_t> ids;
    std::unordered_map<uint64_t, std::set<uint64_t>> by_seed;
  };
  std::unordered_map<const Job*, JobQueue> queues_;
  std::map<Position, Job*> ready_;  // jobs with queued tasks, not held
  std::set<const Job*> held_;
};

}  // namespace pf::server
