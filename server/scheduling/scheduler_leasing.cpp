// Scheduler, part: the queue and the leases — who gets which task, waiters, expiry and
// extension (scheduler.h, "Queue" and "Workers").
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/scheduling/scheduler.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

// ---------------------------------------------------------------------------------------------
// Queue

void Scheduler::Enqueue(Job& job, uint64_t task_id, Effects& fx) {
  if (map_hook_) {
    MapUpdate update;  // a map created for the task: its pieces join the queue
    const bool ready = map_hook_->RenderTaskReady(job, job.task(task_id), update);
    if (!update.empty()) ApplyMapUpdateLocked(update, clock_.Now(), fx);
    if (!ready) {
      held_[{job.id(), job.task(task_id).map_index}].push_back(task_id);
      Touch(job, fx);
      return;
    }
  }
  queue_.Push(job, task_id);
  Touch(job, fx);
}

void Scheduler::Dequeue(Job& job, uint64_t task_id) {
  queue_.Remove(job, task_id);
}

void Scheduler::ServeWaiters(Effects& fx) {
  const double now = clock_.Now();
  for (auto it = waiters_.begin(); it != waiters_.end() && (!queue_.empty() || verification_.HasQueued());) {
    bool restricted = false;
    std::optional<Lease> lease = LeaseLocked(it->second.request, now, fx, &restricted);
    if (lease) {
      fx.callbacks.emplace_back(std::move(it->second.done), std::move(lease));
      it = waiters_.erase(it);
    } else if (restricted) {
      ++it;  // what this worker passed by may be another waiter's
    } else {
      break;  // nothing for a worker that passes nothing by: nothing for anyone
    }
  }
}

bool Scheduler::CheckTimeBudget(Job& job, double now, Effects& fx) {
  // A restarted job's image is empty until its restart is stored: a budget ending it then would
  // call an empty image a success. Its clock starts again once the restart's checkpoint and row are
  // both stored (RestartClock).
  if (job.restart_pending() || !TimeBudgetReached(job, now)) return false;
  if (job.epoch() > 0 && job.count(TaskState::kDone) == 0 && job.count(TaskState::kLeased) == 0) {
    // Restarted after a conviction and nothing merged since: its workers were all convicted or
    // none came. An empty image is no result.
    const std::string why =
        "time budget reached with nothing merged since the job restarted after a conviction";
    FinishJob(job, JobState::kFailed, why, now, fx);
    spdlog::error("job {}: failed: {}", job.id(), why);
    return true;
  }
  const double budget = job.config().stop.time_budget_seconds;
  job.stopping = true;
  uint64_t cancelled = 0;
  for (uint64_t id = 0; id < job.num_tasks(); ++id) {
    if (job.runtime(id).state != TaskState::kQueued) continue;
    // A hierarchical job's emission + direct light tasks (part indirect, radiance_part.h) are the
    // only ones of their pixels: cancelled, those pixels would lose their light sources and
    // direct light, where every other task only adds samples. They stay queued (they are cheap,
    // no map, and leased first anyway), so the job ends after them.
    if (job.task(id).part == RadiancePart::kUnmapped) continue;
    Dequeue(job, id);
    job.SetTaskState(id, TaskState::kCancelled);
    ++cancelled;
  }
  spdlog::info("job {}: time budget {:.3g} s reached: {} queued tasks cancelled, {} still running", job.id(),
               budget, cancelled, job.count(TaskState::kLeased));
  Touch(job, fx);
  MaybeSucceed(job, now, fx);
  return true;
}

std::optional<Lease> Scheduler::LeaseLocked(const LeaseRequest& request, double now, Effects& fx,
                                            bool* restricted) {
  if (shutdown_) return std::nullopt;
  ++counters_.lease_attempts;
  const std::string& worker = request.worker_id;
  bool passed = false;  // work this worker may not take that another might
  PolledLocked(worker, now);
  if (health_.Quarantined(worker, now)) {
    if (restricted) *restricted = true;
    return std::nullopt;
  }
  // A worker with no failed attempt in a running job is blocklisted nowhere and avoids nothing:
  // it skips the checks below (the lease path of a healthy farm).
  const bool failed_before = health_.FailedInActiveJob(worker);
  if (map_hook_ && queue_.has_pieces())
    if (std::optional<Lease> piece = LeasePieceLocked(request, now, failed_before, &passed)) return piece;
  if (verification_.HasQueued())
    if (std::optional<Lease> check = LeaseVerificationLocked(request, now, fx, &passed)) return check;
  std::optional<TaskQueue::Position> after;  // jobs up to here have nothing for this worker
  while (Job* next = queue_.NextJob(after)) {
    Job& job = *next;
    if (CheckTimeBudget(job, now, fx)) continue;  // its queue is gone, or only the tasks it keeps
    if (failed_before && health_.IsBlocklisted(job.id(), worker)) {
      passed = true;
      // This worker is live and may not run the job: if no other live worker may, nobody will
      // (the other workers were lost since it was blocklisted).
      if (const std::string none = NoWorkerLeft(job); !none.empty()) {
        const std::string why = "gave up: " + none;
        FinishJob(job, JobState::kFailed, why, now, fx);
        spdlog::error("job {}: failed: {}", job.id(), why);
        continue;  // its queue is gone
      }
      after = TaskQueue::PositionOf(job);
      continue;
    }
    // A retry goes to another worker first: one that failed the task leaves it while another
    // worker that may take it waits for work (docs/farm.md, "Worker health").
    TaskQueue::Avoid avoid;
    if (failed_before)
      avoid = [&](uint64_t task_id) {
        const TaskRuntime& rt = job.runtime(task_id);
        if (std::find(rt.failed_workers.begin(), rt.failed_workers.end(), worker) ==
                rt.failed_workers.end() ||
            !AnotherWaiterCanTake(job, rt, worker, now))
          return false;
        passed = true;
        return true;
      };
    const std::optional<TaskQueue::Pick> chosen = queue_.Choose(job, request.cached_map_seeds, avoid);
    if (!chosen) {
      after = TaskQueue::PositionOf(job);
      continue;
    }
    const uint64_t pick = chosen->task_id;
    const bool affinity = chosen->map_cached;
    Dequeue(job, pick);
    job.SetTaskState(pick, TaskState::kLeased);
    TaskRuntime& rt = job.runtime(pick);
    ++rt.attempts;
    rt.lease_id = leases_.Issue(job, pick, rt.attempts);
    rt.worker_id = worker;
    rt.lease_deadline = now + options_.lease_seconds;
    rt.progress = 0;
    if (job.state() == JobState::kQueued) {
      job.TransitionTo(JobState::kRunning, now);
      spdlog::info("job {}: running", job.id());
    }
    ++counters_.leases;
    Touch(job, fx);
    spdlog::info("job {} task {}: leased to {} (attempt {}{})", job.id(), pick,
                 limits::Quote(worker, limits::kMaxWorkerIdBytes), rt.attempts,
                 affinity ? ", map cached" : "");
    activity_.TaskEvent(job.id(), "leased", pick, rt.attempts, worker, affinity ? "map cached" : "");
    Lease lease;
    lease.lease_id = rt.lease_id;
    lease.worker_id = worker;
    lease.job_id = job.id();
    lease.task_id = pick;
    lease.attempt = rt.attempts;
    lease.lease_seconds = options_.lease_seconds;
    lease.task = job.task(pick);
    lease.config = job.shared_config();
    return lease;
  }
  if (restricted) *restricted = passed;
  return std::nullopt;
}

std::optional<Lease> Scheduler::LeasePieceLocked(const LeaseRequest& request, double now, bool failed_before,
                                                 bool* passed) {
  const std::string& worker = request.worker_id;
  TaskQueue::MapFilter may_lease;  // not for a worker blocklisted for a job of the map
  if (failed_before)
    may_lease = [&](const std::string& map_key) {
      for (const std::string& job_id : map_hook_->JobsOfMap(map_key))
        if (health_.IsBlocklisted(job_id, worker)) {
          *passed = true;
          return false;
        }
      return true;
    };
  // Its id comes from the one lease table, which keeps the holder and the deadline.
  const MapTracingHook::IssuePieceLease issue = [&](const std::string& job_id, const std::string& map_key,
                                                    uint32_t piece, uint32_t attempt) {
    return leases_.IssuePiece(job_id, map_key, piece, attempt, worker, now + options_.lease_seconds);
  };
  while (const std::optional<TaskQueue::Piece> piece = queue_.ChoosePiece(may_lease)) {
    queue_.RemovePiece(piece->map_seq, piece->index);
    std::optional<Lease> lease;
    try {
      lease = map_hook_->LeasePiece(*piece, worker, issue);
    } catch (...) {
      QueueMapPiecesLocked(piece->map_key);  // still queued in its map: back in the queue
      throw;
    }
    if (lease) {
      lease->worker_id = worker;
      lease->lease_seconds = options_.lease_seconds;
      return lease;
    }
    // Not queued in its map any more: an update made outside this lock and not yet applied (a map
    // left to the workers when a refused upload failed its piece once too often). The map's pieces
    // are set again from it.
    QueueMapPiecesLocked(piece->map_key);
  }
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------
// Workers

std::optional<Lease> Scheduler::TryLease(const LeaseRequest& request) {
  Effects fx;
  std::optional<Lease> lease;
  {
    std::lock_guard lock(mu_);
    lease = LeaseLocked(request, clock_.Now(), fx);
  }
  Run(fx);
  return lease;
}

uint64_t Scheduler::LeaseOrWait(const LeaseRequest& request, double wait_seconds, LeaseCallback done) {
  Effects fx;
  uint64_t id = 0;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    std::optional<Lease> lease = LeaseLocked(request, now, fx);
    if (lease || shutdown_ || !(wait_seconds > 0)) {
      fx.callbacks.emplace_back(std::move(done), std::move(lease));
    } else {
      id = next_waiter_++;
      waiters_[id] = Waiter{request, now + wait_seconds, std::move(done)};
    }
  }
  Run(fx);
  return id;
}

void Scheduler::CancelWait(uint64_t waiter_id) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    auto it = waiters_.find(waiter_id);
    if (it == waiters_.end()) return;
    fx.callbacks.emplace_back(std::move(it->second.done), std::nullopt);
    waiters_.erase(it);
  }
  Run(fx);
}

LeaseTable::Entry* Scheduler::FindLiveLease(const std::string& lease_id, double now, Effects& fx) {
  LeaseTable::Entry* entry = leases_.Find(lease_id);
  if (!entry) return nullptr;
  if (entry->kind == LeaseKind::kMapPiece) {
    // Stored, or its map left to the workers or purged, since: the entry outlived its piece's lease.
    if (!map_hook_ || !map_hook_->PieceLeaseCurrent(entry->map_key, uint32_t(entry->task_id), lease_id)) {
      leases_.Erase(lease_id);
      return nullptr;
    }
    if (now >= entry->deadline) {
      EndPieceLeaseLocked(lease_id, PieceLeaseEnd::Why::kExpired, "", now, fx);
      return nullptr;
    }
    return entry;
  }
  Job& job = *entry->job;
  const uint64_t task_id = entry->task_id;
  // A pinned lease's result arrived in time and is being merged: it decides the attempt.
  if (now >= job.runtime(task_id).lease_deadline && !job.runtime(task_id).merging) {
    ExpireLease(job, task_id, now, fx);
    return nullptr;
  }
  return entry;
}

void Scheduler::EndPieceLeaseLocked(const std::string& lease_id, PieceLeaseEnd::Why why,
                                    const std::string& reason, double now, Effects& fx) {
  const LeaseTable::Entry& e = *leases_.Find(lease_id);
  const PieceLeaseEnd end{why, e.map_key, uint32_t(e.task_id), lease_id, e.worker_id, reason};
  if (!map_hook_) {
    leases_.Erase(lease_id);
    return;
  }
  MapUpdate update;
  try {
    update = map_hook_->PieceLeaseEnded(end);
  } catch (const std::exception& ex) {
    // One piece's bookkeeping failing must not fail the call (a tick expires many leases at once).
    // The entry stays: its map still has the piece leased, and a later tick ends it again, instead
    // of the piece staying leased with no lease behind it.
    spdlog::error("map {} piece {}: the end of lease {} was not recorded (tried again at the next tick): {}",
                  end.map_key.substr(0, 12), end.piece, end.lease_id, ex.what());
    return;
  }
  leases_.Erase(lease_id);
  ApplyMapUpdateLocked(update, now, fx);
  ServeWaiters(fx);
}

bool Scheduler::HolderLocked(const LeaseTable::Entry& entry, const std::string& worker_id,
                             const std::string& call, Effects& fx) {
  if (entry.kind == LeaseKind::kMapPiece) {
    if (entry.worker_id == worker_id) return true;
    // Refused in every job of the map (health and convictions count in each: the first may have ended).
    for (const std::string& job_id : map_hook_->JobsOfMap(entry.map_key))
      NotTheHolderLocked(job_id, entry.task_id, worker_id, entry.worker_id, call, fx, LeaseKind::kMapPiece);
    return false;
  }
  const TaskRuntime& rt = entry.job->runtime(entry.task_id);
  if (rt.worker_id == worker_id) return true;
  NotTheHolderLocked(entry.job->id(), entry.task_id, worker_id, rt.worker_id, call, fx);
  return false;
}

Scheduler::PieceLeaseRef Scheduler::PieceLeaseOf(const std::string& lease_id, const std::string& worker_id,
                                                 const std::string& call) {
  Effects fx;
  PieceLeaseRef ref;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    HeardLocked(worker_id, now);
    LeaseTable::Entry* entry = FindLiveLease(lease_id, now, fx);
    if (entry && entry->kind == LeaseKind::kMapPiece) {
      if (HolderLocked(*entry, worker_id, call, fx))
        ref = PieceLeaseRef{PieceLeaseRef::Status::kLive, entry->map_key, uint32_t(entry->task_id)};
      else
        ref.status = PieceLeaseRef::Status::kNotHolder;
    }
  }
  Run(fx);
  return ref;
}

void Scheduler::ExpireLease(Job& job, uint64_t task_id, double now, Effects& fx) {
  const TaskRuntime& rt = job.runtime(task_id);
  const std::string worker = rt.worker_id;
  ++counters_.expired;
  std::string detail;
  if (health_.LeaseRanOut(worker, rt.lease_deadline - options_.lease_seconds, now)) {
    detail = "no call from the worker since the lease was renewed: marked lost";
    activity_.WorkerLost(worker, true);
    spdlog::warn(
        "worker {}: lost: its lease of job {} task {} ran out with no call from it since it was renewed",
        limits::Quote(worker, limits::kMaxWorkerIdBytes), job.id(), task_id);
  }
  activity_.TaskEvent(job.id(), "expired", task_id, rt.attempts, worker, detail);
  FailAttempt(job, task_id, "lease expired (worker " + worker + ")", true, now, fx);
}

ExtendResult Scheduler::Extend(const std::string& lease_id, const std::string& worker_id, double progress) {
  Effects fx;
  ExtendResult result;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    HeardLocked(worker_id, now);
    if (std::optional<ExtendResult> check = ExtendVerificationLocked(lease_id, worker_id, now, fx)) {
      result = *check;
    } else if (LeaseTable::Entry* ref = FindLiveLease(lease_id, now, fx)) {
      if (!HolderLocked(*ref, worker_id, "ExtendLease", fx)) {
        // A lease id that reached another worker does not keep the work from being re-run.
        result.not_holder = true;
      } else if (ref->kind == LeaseKind::kMapPiece) {
        ref->deadline = now + options_.lease_seconds;
        result = {true, options_.lease_seconds};
      } else {
        TaskRuntime& rt = ref->job->runtime(ref->task_id);
        rt.lease_deadline = now + options_.lease_seconds;
        rt.progress = std::isfinite(progress) ? std::clamp(progress, 0.0, 1.0) : 0.0;
        result = {true, options_.lease_seconds};
      }
    }
  }
  Run(fx);
  return result;
}

}  // namespace pf::server
