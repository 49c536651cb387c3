#pragma once
// All jobs the coordinator knows, by id and in submission order, and the allocation of job ids
// ("job-" and 32 random hex digits; the seq, increasing across restarts, orders them). Not
// thread-safe: the Scheduler's lock guards it. Jobs are shared: whoever holds a Job beyond the lock
// holds it by Shared (a deleted job, Remove, lives until the last holder lets go).

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "server/jobs/job.h"

namespace pf::server {

inline const std::string kJobIdPrefix = "job-";

class JobRegistry {
 public:
  // A fresh (seq, id) pair; seqs are never reused.
  std::pair<uint64_t, std::string> Allocate();
  // Recovery: later allocations start above `seq`.
  void ReserveUpTo(uint64_t seq);

  Job& Add(std::unique_ptr<Job> job);
  Job* Find(const std::string& id);
  const Job* Find(const std::string& id) const;
  // Throws NotFoundError("job_id: unknown job '<id>'").
  Job& Get(const std::string& id);
  const Job& Get(const std::string& id) const;
  // The job as its owners hold it (NotFoundError like Get).
  std::shared_ptr<Job> Shared(const std::string& id) const;
  // Forgets the job (pf delete): Find, Resolve and InSubmissionOrder no longer see it; its id and
  // seq are never allocated again. NotFoundError for an unknown id.
  std::shared_ptr<Job> Remove(const std::string& id);
  // The id a user typed: an exact id, or a unique prefix of one (with or without "job-": ids are
  // long random hex, docs/farm.md "Job ids"). Throws NotFoundError when nothing matches and
  // InputError naming the field and listing the candidates when several do.
  const std::string& Resolve(const std::string& id_or_prefix) const;
  std::vector<Job*> InSubmissionOrder() const;
  size_t size() const { return by_id_.size(); }

 private:
  uint64_t last_seq_ = 0;
  std::unordered_map<std::string, std::shared_ptr<Job>> by_id_;
  std::map<uint64_t, Job*> by_seq_;
};

}  // namespace pf::server
