#pragma once
// Worker health for a Scheduler (server/scheduling/scheduler.h; docs/farm.md "Worker health"):
// which workers may get which work, decided from the failed attempts attributed to them, and which
// workers are still there.
//
//   blocklist   a worker with `blocklist_failures` failed attempts in one job (any kind: FailTask,
//               a lease that ran out, a rejected result, of render tasks and map pieces alike)
//               gets no more of that job's work. One bad worker then costs a job that many
//               attempts, not the job: without it, a worker that fails in 5 ms took every retry of
//               a task while a healthy worker was busy, and the task's attempts ran out.
//   quarantine  a worker blocklisted by `quarantine_jobs` jobs within `quarantine_seconds` gets no
//               leases at all for `quarantine_seconds` (a broken install fails every job it
//               touches; a blocklist per job would let it spoil each new job's first attempts).
//   lost        a worker that stopped calling: a lease of it ran out and it has not called since
//               the lease was last renewed, or it has not called for `lost_seconds` (two lease
//               periods) with no long poll open. Live again at its next call. Lost workers do not
//               count as workers that could still run a job (Scheduler: "no worker left").
//   left        a worker that said it is leaving (LeaveFarm): offline, never lost while silent,
//               and, like a lost one, no worker that could still run a job. Online again at its
//               next call.
//
// In memory only: a restarted coordinator starts with every worker healthy (FarmActivity, which
// is stored, shows no quarantine or blocklist of a past life for that reason)
// (the durable record of a task is its attempt and failure counts). Not thread-safe: the
// Scheduler's lock guards it, as it guards the lease table.

#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

namespace pf::server {

struct WorkerHealthOptions {
  uint32_t blocklist_failures = 3;  // failed attempts in one job that blocklist a worker (0 = never)
  uint32_t quarantine_jobs = 3;     // blocklisted by this many jobs within the window (0 = never)
  double quarantine_seconds = 900;  // the window, and how long a quarantine lasts
  double lost_seconds = 60;         // silence (no call, no open long poll) that makes a worker lost
};

class WorkerHealth {
 public:
  struct Blocklisted {
    uint32_t failed_attempts = 0;
    std::string last_error;
  };
  struct FailureOutcome {
    bool blocklisted = false;  // just now (not before) blocklisted for the job
    uint32_t failed_attempts = 0;
    bool quarantined = false;  // just now quarantined
    std::string quarantine_reason;
  };

  explicit WorkerHealth(WorkerHealthOptions options) : options_(options) {}
  const WorkerHealthOptions& options() const { return options_; }

  // A LeaseTask (or a long poll still open) from the worker: a worker is known from its first
  // poll on. True if it was lost: it is live again.
  bool Polled(const std::string& worker_id, double now);
  // Another call naming the worker (ExtendLease, CompleteTask, FailTask, an upload): as Polled,
  // but an id never seen polling stays unknown (a stranger naming itself in a call about someone
  // else's lease is no worker of the farm).
  bool Heard(const std::string& worker_id, double now);
  // A lease of the worker ran out; it was last renewed (leased or extended) at `renewed`. True if
  // that makes the worker lost (no call from it since).
  bool LeaseRanOut(const std::string& worker_id, double renewed, double now);
  // Workers that just became lost by silence (see the header comment), with their silence.
  std::vector<std::pair<std::string, double>> MarkSilentLost(double now);
  bool Lost(const std::string& worker_id) const;
  // The worker said it is leaving (LeaveFarm): it is not marked lost while it stays silent. Its
  // next call (Polled, Heard) makes it online again. False for a worker never seen.
  bool Left(const std::string& worker_id);
  bool HasLeft(const std::string& worker_id) const;

  // A failed attempt attributed to the worker in the job (`reason` for the blocklist entry).
  // `convicted`: it sent a result that another render proved wrong (docs/farm.md, "Result
  // verification"): blocklisted at once, whatever its count.
  FailureOutcome RecordFailure(const std::string& job_id, const std::string& worker_id,
                               const std::string& reason, double now, bool convicted = false);
  // Blocklisted for the job at once, without counting towards a quarantine (a lease hijack: the
  // id may be anyone's, docs/security.md). False if it already was.
  bool Blocklist(const std::string& job_id, const std::string& worker_id, const std::string& reason,
                 double now);
  bool IsBlocklisted(const std::string& job_id, const std::string& worker_id) const;
  // Whether the worker has a failed attempt in a job that has not ended: if not, no job's
  // blocklist names it and no task avoids it (the scheduler's fast path for healthy workers).
  bool FailedInActiveJob(const std::string& worker_id) const;
  bool Quarantined(const std::string& worker_id, double now) const;
  // The job's blocklist by worker id (JobStatus.blocklisted_workers), empty if none.
  const std::map<std::string, Blocklisted>& BlocklistOf(const std::string& job_id) const;
  // Whether a worker that is heard from and not lost is left that is not blocklisted for the job
  // (quarantined ones count: their quarantine ends).
  bool AnyLiveWorkerMayRun(const std::string& job_id) const;
  // Whether a live (heard from, not lost), not quarantined worker is left that `eligible` accepts
  // (who may verify a result: docs/farm.md "Result verification").
  bool AnyLiveWorker(const std::function<bool(const std::string& worker_id)>& eligible, double now) const;
  // The job ended: its failure counts are dropped (its blocklist stays, for its status).
  void JobEnded(const std::string& job_id);
  // A deleted job (pf delete): its blocklist goes too.
  void ForgetJob(const std::string& job_id);

 private:
  struct Worker {
    double last_call = 0;
    bool lost = false;
    bool left = false;                // said it is leaving (LeaveFarm) and has not called since
    uint32_t active_jobs_failed = 0;  // jobs not ended with a failed attempt of it
    double quarantined_until = -std::numeric_limits<double>::infinity();
    std::deque<std::pair<double, std::string>> blocklistings;  // (when, job) within the window
  };
  struct JobHealth {
    std::unordered_map<std::string, uint32_t> failures;  // failed attempts per worker, while active
    std::map<std::string, Blocklisted> blocklisted;
  };
  Worker& WorkerOf(const std::string& worker_id, double now);

  WorkerHealthOptions options_;
  std::unordered_map<std::string, Worker> workers_;
  std::unordered_map<std::string, JobHealth> jobs_;
};

}  // namespace pf::server
