#include "server/scheduling/lease_table.h"

#include <algorithm>

#include "server/jobs/random_id.h"

namespace pf::server {

std::string LeaseTable::MakeId(const Job& job, uint64_t task_id, uint32_t attempt) {
  return job.id() + "." + std::to_string(task_id) + "." + std::to_string(attempt) + "." + RandomHex(16);
}

std::string LeaseTable::Issue(Job& job, uint64_t task_id, uint32_t attempt) {
  std::string id = MakeId(job, task_id, attempt);
  leases_[id] = {&job, task_id};
  return id;
}

LeaseTable::Entry* LeaseTable::Find(const std::string& lease_id) {
  auto it = leases_.find(lease_id);
  return it == leases_.end() ? nullptr : &it->second;
}

std::vector<std::string> LeaseTable::Expired(double now) const {
  std::vector<std::string> out;
  for (const auto& [id, e] : leases_)
    if (now >= e.job->runtime(e.task_id).lease_deadline) out.push_back(id);
  return out;
}

double LeaseTable::ProgressOf(const Job& job) const {
  double sum = 0;
  for (const auto& [id, e] : leases_)
    if (e.job == &job)
      sum += std::clamp(job.runtime(e.task_id).progress, 0.0, 1.0) * double(job.task_work(e.task_id));
  return sum;
}

}  // namespace pf::server
