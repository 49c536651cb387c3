#include "server/jobs/job_registry.h"

#include <stdexcept>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/errors.h"
#include "server/jobs/random_id.h"

namespace pf::server {

std::pair<uint64_t, std::string> JobRegistry::Allocate() {
  ++last_seq_;
  // The sequence number orders jobs; the id is random (random_id.h): never reused.
  return {last_seq_, kJobIdPrefix + RandomHex(16)};
}

void JobRegistry::ReserveUpTo(uint64_t seq) {
  if (seq > last_seq_) last_seq_ = seq;
}

Job& JobRegistry::Add(std::unique_ptr<Job> job) {
  Job& ref = *job;
  if (by_seq_.count(ref.seq()) || by_id_.count(ref.id()))
    throw std::logic_error("JobRegistry: duplicate job " + ref.id());
  ReserveUpTo(ref.seq());
  by_seq_[ref.seq()] = &ref;
  by_id_[ref.id()] = std::move(job);
  return ref;
}

Job* JobRegistry::Find(const std::string& id) {
  auto it = by_id_.find(id);
  return it == by_id_.end() ? nullptr : it->second.get();
}

const Job* JobRegistry::Find(const std::string& id) const {
  auto it = by_id_.find(id);
  return it == by_id_.end() ? nullptr : it->second.get();
}

Job& JobRegistry::Get(const std::string& id) {
  Job* job = Find(id);
  if (!job) throw NotFoundError("job_id: unknown job " + limits::Quote(id));
  return *job;
}

const Job& JobRegistry::Get(const std::string& id) const {
  const Job* job = Find(id);
  if (!job) throw NotFoundError("job_id: unknown job " + limits::Quote(id));
  return *job;
}

std::shared_ptr<Job> JobRegistry::Shared(const std::string& id) const {
  auto it = by_id_.find(id);
  if (it == by_id_.end()) throw NotFoundError("job_id: unknown job " + limits::Quote(id));
  return it->second;
}

std::shared_ptr<Job> JobRegistry::Remove(const std::string& id) {
  auto it = by_id_.find(id);
  if (it == by_id_.end()) throw NotFoundError("job_id: unknown job " + limits::Quote(id));
  std::shared_ptr<Job> job = std::move(it->second);
  by_id_.erase(it);
  by_seq_.erase(job->seq());
  return job;
}

const std::string& JobRegistry::Resolve(const std::string& id_or_prefix) const {
  if (auto it = by_id_.find(id_or_prefix); it != by_id_.end()) return it->first;
  const std::string prefix =
      id_or_prefix.rfind(kJobIdPrefix, 0) == 0 ? id_or_prefix : kJobIdPrefix + id_or_prefix;
  std::vector<const std::string*> matches;  // in submission order, so the listing is stable
  if (prefix.size() > kJobIdPrefix.size()) {
    for (const auto& [seq, job] : by_seq_)
      if (job->id().compare(0, prefix.size(), prefix) == 0) matches.push_back(&job->id());
  }
  if (matches.size() == 1) return *matches[0];
  if (matches.empty()) throw NotFoundError("job_id: unknown job " + limits::Quote(id_or_prefix));
  constexpr size_t kListed = 10;
  std::string list;
  for (size_t i = 0; i < matches.size() && i < kListed; ++i) list += (i ? ", " : "") + *matches[i];
  if (matches.size() > kListed) list += ", ...";
  throw InputError("job_id: " + limits::Quote(id_or_prefix) +
                   " is ambiguous: " + std::to_string(matches.size()) + " jobs match (" + list + ")");
}

std::vector<Job*> JobRegistry::InSubmissionOrder() const {
  std::vector<Job*> jobs;
  jobs.reserve(by_seq_.size());
  for (const auto& [seq, job] : by_seq_) jobs.push_back(job);
  return jobs;
}

}  // namespace pf::server
