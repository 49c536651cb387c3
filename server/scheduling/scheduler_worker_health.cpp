// Scheduler, part: worker health — polls, failures counted per worker, convictions, returned
// leases (worker_health.h).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/scheduling/scheduler.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

// ---------------------------------------------------------------------------------------------
// Worker health (worker_health.h)

void Scheduler::WorkerLeft(const std::string& worker_id) {
  std::lock_guard lock(mu_);
  if (!health_.Left(worker_id)) return;  // never seen polling: no worker of the farm
  activity_.WorkerOffline(worker_id, true);
  spdlog::info("worker {}: left the farm (offline)", limits::Quote(worker_id, limits::kMaxWorkerIdBytes));
}

void Scheduler::PolledLocked(const std::string& worker_id, double now) {
  // Online again if it had left (only then: this runs for every parked poll at every tick).
  if (health_.HasLeft(worker_id)) activity_.WorkerOffline(worker_id, false);
  if (!health_.Polled(worker_id, now)) return;
  activity_.WorkerLost(worker_id, false);
  spdlog::info("worker {}: live again (it called)", limits::Quote(worker_id, limits::kMaxWorkerIdBytes));
}

void Scheduler::HeardLocked(const std::string& worker_id, double now) {
  if (health_.HasLeft(worker_id)) activity_.WorkerOffline(worker_id, false);
  if (!health_.Heard(worker_id, now)) return;
  activity_.WorkerLost(worker_id, false);
  spdlog::info("worker {}: live again (it called)", limits::Quote(worker_id, limits::kMaxWorkerIdBytes));
}

bool Scheduler::CountFailure(Job& job, const std::string& worker_id, uint64_t task_id, uint32_t attempt,
                             const std::string& reason, double now, bool convicted) {
  const WorkerHealth::FailureOutcome out = health_.RecordFailure(job.id(), worker_id, reason, now, convicted);
  const std::string who = limits::Quote(worker_id, limits::kMaxWorkerIdBytes);
  if (out.blocklisted) {
    spdlog::warn(
        "job {}: worker {} blocklisted after {} failed attempts in this job (last: {}): it gets no "
        "more of its tasks or map pieces",
        job.id(), who, out.failed_attempts, reason);
    activity_.TaskEvent(job.id(), "blocklisted", task_id, attempt, worker_id,
                        "after " + std::to_string(out.failed_attempts) +
                            " failed attempts in this job: no more of its tasks or map pieces");
    activity_.WorkerBlocklisted(worker_id, job.id());
  }
  if (out.quarantined) {
    const double seconds = health_.options().quarantine_seconds;
    spdlog::error("worker {}: quarantined for {:.0f} s, no leases of any job: {}", who, seconds,
                  out.quarantine_reason);
    activity_.TaskEvent(
        job.id(), "quarantined", task_id, attempt, worker_id,
        "no leases of any job for " + std::to_string(int64_t(seconds)) + " s: " + out.quarantine_reason);
    activity_.WorkerQuarantined(worker_id, now + seconds, out.quarantine_reason);
  }
  return out.blocklisted;
}

std::string Scheduler::NoWorkerLeft(const Job& job) const {
  const auto& blocklist = health_.BlocklistOf(job.id());
  // A job no worker was ever blocklisted for waits for workers, as any job does. So does a job
  // whose blocklisted workers were all convicted (or presented another's lease): the job is not
  // broken, those workers are, and the honest workers of the farm may not have called yet.
  const bool only_convicted = std::all_of(blocklist.begin(), blocklist.end(), [&](const auto& entry) {
    return std::find(job.convicted_workers.begin(), job.convicted_workers.end(), entry.first) !=
           job.convicted_workers.end();
  });
  if (only_convicted || health_.AnyLiveWorkerMayRun(job.id())) return "";
  std::string names;
  for (const auto& [worker, entry] : blocklist)
    names += (names.empty() ? "" : ", ") + worker + " after " + std::to_string(entry.failed_attempts) +
             " failed attempts";
  return "no worker left to run the job: blocklisted for it: " + names + "; no other live worker";
}

bool Scheduler::AnotherWaiterCanTake(const Job& job, const TaskRuntime& rt, const std::string& worker_id,
                                     double now) const {
  for (const auto& [id, waiter] : waiters_) {
    const std::string& other = waiter.request.worker_id;
    if (other == worker_id || health_.Quarantined(other, now) || health_.IsBlocklisted(job.id(), other) ||
        std::find(rt.failed_workers.begin(), rt.failed_workers.end(), other) != rt.failed_workers.end())
      continue;
    return true;
  }
  return false;
}

void Scheduler::PieceAttemptFailedLocked(const PieceFailure& f, double now, Effects& fx) {
  Job* job = jobs_.Find(f.job_id);
  if (!job) return;
  activity_.TaskEvent(f.job_id, f.kind, f.piece, f.attempt, f.worker_id, f.reason);
  if (job->active() && CountFailure(*job, f.worker_id, f.piece, f.attempt, f.reason, now)) {
    if (const std::string none = NoWorkerLeft(*job); !none.empty()) {
      const std::string why = "map piece " + std::to_string(f.piece) + " attempt " +
                              std::to_string(f.attempt) + " failed: " + f.reason + "; gave up: " + none;
      FinishJob(*job, JobState::kFailed, why, now, fx);
      spdlog::error("job {}: failed: {}", f.job_id, why);
    }
  }
}

FailOutcome Scheduler::Fail(const std::string& lease_id, const std::string& worker_id,
                            const std::string& reason, bool retryable) {
  Effects fx;
  FailOutcome outcome = FailOutcome::kUnknownLease;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    HeardLocked(worker_id, now);
    if (std::optional<FailOutcome> check = FailVerificationLocked(lease_id, worker_id, reason, now, fx)) {
      outcome = *check;
    } else if (LeaseTable::Entry* ref = FindLiveLease(lease_id, now, fx)) {
      if (ref->kind == LeaseKind::kMapPiece) {
        // A piece: queued again, the failure counted against its worker (the hook's update);
        // `retryable` does not apply (a piece is left to the workers instead).
        if (HolderLocked(*ref, worker_id, "FailTask", fx)) {
          outcome = FailOutcome::kFailed;
          EndPieceLeaseLocked(lease_id, PieceLeaseEnd::Why::kFailed, reason, now, fx);
        } else {
          outcome = FailOutcome::kNotHolder;
        }
      } else if (const TaskRuntime& rt = ref->job->runtime(ref->task_id); rt.merging) {
        // The result it sent is being merged; that decides the attempt (kUnknownLease: the lease
        // is as good as finished).
        spdlog::info("job {} task {}: FailTask ignored: its result is being merged", ref->job->id(),
                     ref->task_id);
      } else if (!HolderLocked(*ref, worker_id, "FailTask", fx)) {
        // A lease id that reached another worker (a log, a copied command line) does not let it
        // end the task — with retryable = false, the whole job.
        outcome = FailOutcome::kNotHolder;
      } else {
        outcome = FailOutcome::kFailed;
        activity_.TaskEvent(ref->job->id(), "failed", ref->task_id, rt.attempts, rt.worker_id,
                            reason + (retryable ? "" : " (not retryable)"));
        FailAttempt(*ref->job, ref->task_id, "worker: " + reason, retryable, now, fx);
      }
    }
  }
  Run(fx);
  return outcome;
}

void Scheduler::ReturnLease(const std::string& lease_id) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    LeaseTable::Entry* entry = nullptr;
    if (ReturnVerificationLocked(lease_id, fx)) {
      ServeWaiters(fx);
    } else if (entry = leases_.Find(lease_id); entry && entry->kind == LeaseKind::kMapPiece) {
      // A piece: queued again at once, its attempt not counted.
      const std::string map_key = entry->map_key;
      const uint32_t piece = uint32_t(entry->task_id);
      leases_.Erase(lease_id);
      if (map_hook_)
        ApplyMapUpdateLocked(map_hook_->PieceReturned(map_key, piece, lease_id), clock_.Now(), fx);
      ServeWaiters(fx);
    } else {
      if (!entry || entry->job->runtime(entry->task_id).merging) return;
      Job& job = *entry->job;
      const uint64_t task_id = entry->task_id;
      leases_.Erase(lease_id);
      ++counters_.returned;
      activity_.TaskEvent(job.id(), "returned", task_id, job.runtime(task_id).attempts,
                          job.runtime(task_id).worker_id, "the lease never reached the worker");
      job.SetTaskState(task_id, TaskState::kQueued);
      Enqueue(job, task_id, fx);
      spdlog::debug("job {} task {}: undelivered lease returned", job.id(), task_id);
      ServeWaiters(fx);
    }
  }
  Run(fx);
}

bool Scheduler::ConvictWorker(const std::string& job_id, const std::string& worker_id, uint64_t task_id,
                              const std::string& evidence) {
  return Convict(job_id, {worker_id}, task_id, evidence, std::nullopt, 0);  // scheduler_verification.cpp
}

uint32_t Scheduler::JobEpoch(const std::string& job_id) {
  std::lock_guard lock(mu_);
  const Job* job = jobs_.Find(job_id);
  return job ? job->epoch() : 0;
}

uint64_t Scheduler::StoredMergeSeq(const std::string& job_id) {
  std::lock_guard lock(mu_);
  const Job* job = jobs_.Find(job_id);
  // A job unknown here was deleted (pf delete) after the merge: nothing of it is written again.
  return job ? job->checkpoint_written_seq : ~uint64_t(0);
}

void Scheduler::RestoreConvictions(const std::string& job_id, const std::vector<std::string>& workers) {
  std::lock_guard lock(mu_);
  Job* job = jobs_.Find(job_id);
  if (!job) return;
  const double now = clock_.Now();
  for (const std::string& w : workers) {
    // Blocklisted again; its quarantine count was taken when it was convicted.
    health_.Blocklist(job->id(), w, "convicted before the coordinator restarted", now);
    job->convicted_workers.push_back(w);
  }
  if (!workers.empty()) job->row_dirty = true;  // the row may lack them (a checkpoint stored without its row)
}

}  // namespace pf::server
