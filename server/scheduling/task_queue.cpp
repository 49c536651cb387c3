#include "server/scheduling/task_queue.h"

namespace pf::server {

void TaskQueue::Push(Job& job, uint64_t task_id) {
  JobQueue& q = queues_[&job];
  if (q.ids.empty()) ready_[{-int64_t(job.config().priority), job.seq()}] = &job;
  q.ids.insert(task_id);
  q.by_seed[job.task(task_id).map_seed].insert(task_id);
}

void TaskQueue::Remove(Job& job, uint64_t task_id) {
  auto qit = queues_.find(&job);
  if (qit == queues_.end()) return;
  JobQueue& q = qit->second;
  if (!q.ids.erase(task_id)) return;
  auto sit = q.by_seed.find(job.task(task_id).map_seed);
  if (sit != q.by_seed.end()) {
    sit->second.erase(task_id);
    if (sit->second.empty()) q.by_seed.erase(sit);
  }
  if (q.ids.empty()) {
    ready_.erase({-int64_t(job.config().priority), job.seq()});
    queues_.erase(qit);
  }
}

TaskQueue::Pick TaskQueue::Choose(const Job& job, std::span<const uint64_t> cached_map_seeds) const {
  const JobQueue& q = queues_.at(&job);
  Pick pick{*q.ids.begin(), false};
  for (uint64_t seed : cached_map_seeds) {
    auto it = q.by_seed.find(seed);
    if (it == q.by_seed.end() || it->second.empty()) continue;
    const uint64_t candidate = *it->second.begin();
    if (!pick.map_cached || candidate < pick.task_id) pick.task_id = candidate;
    pick.map_cached = true;
  }
  return pick;
}

}  // namespace pf::server
