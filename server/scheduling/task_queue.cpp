#include "server/scheduling/task_queue.h"

namespace pf::server {

void TaskQueue::Push(Job& job, uint64_t task_id) {
  JobQueue& q = queues_[&job];
  if (q.ids.empty() && !held_.count(&job)) ready_[PositionOf(job)] = &job;
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
    ready_.erase(PositionOf(job));
    queues_.erase(qit);
  }
}

void TaskQueue::Hold(const Job& job) {
  held_.insert(&job);
  ready_.erase(PositionOf(job));
}

bool TaskQueue::Unhold(Job& job) {
  if (!held_.erase(&job)) return false;
  if (auto it = queues_.find(&job); it != queues_.end() && !it->second.ids.empty())
    ready_[PositionOf(job)] = &job;
  return true;
}

void TaskQueue::Forget(const Job& job) {
  queues_.erase(&job);
  held_.erase(&job);
  if (auto it = ready_.find(PositionOf(job)); it != ready_.end() && it->second == &job) ready_.erase(it);
}

TaskQueue::Position TaskQueue::PositionOf(const Job& job) {
  return {-int64_t(job.config().priority), job.seq()};
}

Job* TaskQueue::NextJob(const std::optional<Position>& after) const {
  auto it = after ? ready_.upper_bound(*after) : ready_.begin();
  return it == ready_.end() ? nullptr : it->second;
}

std::optional<TaskQueue::Pick> TaskQueue::Choose(const Job& job, std::span<const uint64_t> cached_map_seeds,
                                                 const Avoid& avoid) const {
  const JobQueue& q = queues_.at(&job);
  // The lowest id not avoided in `ids` (avoided tasks are few: a worker's own failed tasks).
  const auto first = [&](const std::set<uint64_t>& ids) -> std::optional<uint64_t> {
    for (uint64_t id : ids)
      if (!avoid || !avoid(id)) return id;
    return std::nullopt;
  };
  std::optional<Pick> pick;
  if (const std::optional<uint64_t> id = first(q.ids)) pick = Pick{*id, false};
  if (!pick) return std::nullopt;
  for (uint64_t seed : cached_map_seeds) {
    auto it = q.by_seed.find(seed);
    if (it == q.by_seed.end() || it->second.empty()) continue;
    const std::optional<uint64_t> candidate = first(it->second);
    if (!candidate) continue;
    if (!pick->map_cached || *candidate < pick->task_id) pick->task_id = *candidate;
    pick->map_cached = true;
  }
  return pick;
}

void TaskQueue::SetMapPieces(const std::string& map_key, uint64_t map_seq,
                             std::span<const uint32_t> indices) {
  if (indices.empty()) {
    pieces_.erase(map_seq);
    return;
  }
  MapPieces& m = pieces_[map_seq];
  m.key = map_key;
  m.indices = std::set<uint32_t>(indices.begin(), indices.end());
}

void TaskQueue::RemovePiece(uint64_t map_seq, uint32_t index) {
  auto it = pieces_.find(map_seq);
  if (it == pieces_.end()) return;
  it->second.indices.erase(index);
  if (it->second.indices.empty()) pieces_.erase(it);
}

size_t TaskQueue::queued_pieces() const {
  size_t n = 0;
  for (const auto& [seq, m] : pieces_) n += m.indices.size();
  return n;
}

std::optional<TaskQueue::Piece> TaskQueue::ChoosePiece(const MapFilter& may_lease) const {
  for (const auto& [seq, m] : pieces_)  // oldest map first; a map here has queued pieces
    if (!may_lease || may_lease(m.key)) return Piece{m.key, seq, *m.indices.begin()};
  return std::nullopt;
}

}  // namespace pf::server
