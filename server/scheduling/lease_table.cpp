#include "server/scheduling/lease_table.h"

#include <algorithm>

#include "server/jobs/random_id.h"

namespace pf::server {

std::string LeaseTable::MakeId(std::string_view job_id, uint64_t task_id, uint32_t attempt) {
  return std::string(job_id) + "." + std::to_string(task_id) + "." + std::to_string(attempt) + "." +
         RandomHex(16);
}

std::string LeaseTable::Issue(Job& job, uint64_t task_id, uint32_t attempt) {
  std::string id = MakeId(job.id(), task_id, attempt);
  Entry& e = leases_[id];
  e.kind = LeaseKind::kRenderTask;
  e.job = &job;
  e.task_id = task_id;
  return id;
}

std::string LeaseTable::IssuePiece(const std::string& job_id, const std::string& map_key, uint32_t piece,
                                   uint32_t attempt, const std::string& worker_id, double deadline) {
  std::string id = MakeId(job_id, piece, attempt);
  Entry& e = leases_[id];
  e.kind = LeaseKind::kMapPiece;
  e.task_id = piece;
  e.map_key = map_key;
  e.worker_id = worker_id;
  e.deadline = deadline;
  return id;
}

LeaseTable::Entry* LeaseTable::Find(const std::string& lease_id) {
  auto it = leases_.find(lease_id);
  return it == leases_.end() ? nullptr : &it->second;
}

std::vector<std::string> LeaseTable::Expired(double now) const {
  std::vector<std::string> out;
  for (const auto& [id, e] : leases_) {
    const double deadline =
        e.kind == LeaseKind::kRenderTask ? e.job->runtime(e.task_id).lease_deadline : e.deadline;
    if (now >= deadline) out.push_back(id);
  }
  return out;
}

double LeaseTable::ProgressOf(const Job& job) const {
  double sum = 0;
  for (const auto& [id, e] : leases_)
    if (e.kind == LeaseKind::kRenderTask && e.job == &job)
      sum += std::clamp(job.runtime(e.task_id).progress, 0.0, 1.0) * double(job.task_work(e.task_id));
  return sum;
}

}  // namespace pf::server
