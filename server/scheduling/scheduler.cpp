// The Scheduler (scheduler.h): construction, the one place effects leave the lock (Run), the
// tick, and the photon-map hook. Its other parts, one concept each: scheduler_jobs.cpp
// (admission, status), scheduler_leasing.cpp (queue, leases), scheduler_completion.cpp (results),
// scheduler_worker_health.cpp, scheduler_persistence.cpp (PersistSource), scheduler_verification.cpp.
#include "server/scheduling/scheduler.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

Scheduler::Scheduler(const Clock& clock, SchedulerOptions options, TaskSourceFactory task_sources)
    : clock_(clock),
      options_(options),
      task_sources_(std::move(task_sources)),
      health_(WorkerHealthOptions{.blocklist_failures = options.blocklist_failures,
                                  .quarantine_jobs = options.quarantine_jobs,
                                  .quarantine_seconds = options.quarantine_seconds,
                                  .lost_seconds = 2 * options.lease_seconds}),
      activity_(clock),
      verification_(options.verification) {
  if (!(options_.lease_seconds > 0)) throw std::invalid_argument("Scheduler: lease_seconds must be > 0");
  if (options_.max_attempts < 1) throw std::invalid_argument("Scheduler: max_attempts must be >= 1");
  if (!(options_.quarantine_seconds >= 0))
    throw std::invalid_argument("Scheduler: quarantine_seconds must be >= 0");
}

Scheduler::~Scheduler() = default;

void Scheduler::SetChangeListener(std::function<void(const std::string&)> listener) {
  std::lock_guard lock(mu_);
  change_listener_ = std::move(listener);
}

void Scheduler::SetPersistListener(std::function<void()> listener) {
  std::lock_guard lock(mu_);
  persist_listener_ = std::move(listener);
}

void Scheduler::Run(Effects& fx) {
  std::function<void(const std::string&)> change;
  std::function<void()> persist;
  RefereeHook* referee = nullptr;
  {
    std::lock_guard lock(mu_);
    change = change_listener_;
    persist = persist_listener_;
    referee = referee_;
  }
  for (auto& [done, lease] : fx.callbacks) done(std::move(lease));
  for (RefereeCase& c : fx.referee) {
    if (referee)
      referee->Judge(std::move(c));
    else
      RefereeVerdict(c.verification_id, "", "no referee");
  }
  if (fx.persist && persist) persist();
  if (change)
    for (const std::string& id : fx.changed) change(id);
  for (const Effects::Hijack& h : fx.hijacks)
    BlocklistForHijack(h.job_id, h.worker_id, h.task_id, h.evidence);
}

void Scheduler::NotTheHolderLocked(const std::string& job_id, uint64_t task_id, const std::string& worker_id,
                                   const std::string& holder, const std::string& call, Effects& fx,
                                   LeaseKind kind) {
  const char* what = kind == LeaseKind::kMapPiece ? "map piece" : "task";
  spdlog::warn("job {} {} {}: {} from worker {} refused: the lease is held by {}", job_id, what, task_id,
               call, limits::Quote(worker_id, limits::kMaxWorkerIdBytes), holder);
  fx.hijacks.push_back(
      {job_id, worker_id, task_id,
       call + " with the lease of " + what + " " + std::to_string(task_id) + ", held by another worker"});
}

void Scheduler::Touch(Job& job, Effects& fx) {
  fx.changed.insert(job.id());
  fx.persist = true;
}

// ---------------------------------------------------------------------------------------------
// Time

void Scheduler::Tick() {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    // A long poll still open is a call in progress: a worker waiting for work is not silent. Not
    // one of a worker that has left: its poll's cancellation may reach us after its LeaveFarm.
    for (const auto& [id, waiter] : waiters_)
      if (!health_.HasLeft(waiter.request.worker_id)) PolledLocked(waiter.request.worker_id, now);
    // Leases of both kinds, through the one path: it expires what ran out (a task whose result
    // arrived in time is pinned: Complete decides it).
    for (const std::string& id : leases_.Expired(now)) FindLiveLease(id, now, fx);
    for (const auto& [worker, silent] : health_.MarkSilentLost(now)) {
      activity_.WorkerLost(worker, true);
      spdlog::warn("worker {}: lost: no call for {:.0f} s", limits::Quote(worker, limits::kMaxWorkerIdBytes),
                   silent);
    }
    TickVerificationLocked(now, fx);
    for (Job* job : jobs_.InSubmissionOrder()) {
      if (job->active() && job->config().stop.time_budget_seconds > 0) CheckTimeBudget(*job, now, fx);
      // Elapsed time was saved only on state changes, so a restart reset a running job's clock
      // (and its time budget). Now it is persisted at least every kElapsedPersistSeconds; a
      // restart loses at most that much, plus the downtime, which does not count.
      if (job->state() == JobState::kRunning && now - job->elapsed_marked_at >= kElapsedPersistSeconds) {
        job->elapsed_marked_at = now;
        job->row_dirty = true;
        fx.persist = true;
      }
    }
    for (auto it = waiters_.begin(); it != waiters_.end();) {
      if (now >= it->second.deadline) {
        fx.callbacks.emplace_back(std::move(it->second.done), std::nullopt);
        it = waiters_.erase(it);
      } else {
        ++it;
      }
    }
  }
  Run(fx);
}

// ---------------------------------------------------------------------------------------------
// Photon maps traced once (map_tracing_hook.h)

void Scheduler::SetMapTracingHook(MapTracingHook* work) {
  std::lock_guard lock(mu_);
  map_hook_ = work;
}

void Scheduler::ApplyMapUpdate(const MapUpdate& update) {
  if (update.empty()) return;
  Effects fx;
  {
    std::lock_guard lock(mu_);
    ApplyMapUpdateLocked(update, clock_.Now(), fx);
    ServeWaiters(fx);
  }
  Run(fx);
}

void Scheduler::ApplyMapUpdateLocked(const MapUpdate& update, double now, Effects& fx) {
  if (!map_hook_) return;
  for (const std::string& key : update.maps) QueueMapPiecesLocked(key);
  for (const PieceFailure& failure : update.failures) PieceAttemptFailedLocked(failure, now, fx);
  for (const auto& [job_id, map_index] : update.release) ReleaseMapLocked(job_id, map_index, fx);
}

void Scheduler::QueueMapPiecesLocked(const std::string& map_key) {
  const MapTracingHook::QueuedPieces queued = map_hook_->QueuedPiecesOf(map_key);
  queue_.SetMapPieces(map_key, queued.map_seq, queued.pieces);
}

void Scheduler::ReleaseMapLocked(const std::string& job_id, uint64_t map_index, Effects& fx) {
  auto it = held_.find({job_id, map_index});
  if (it == held_.end()) return;
  const std::vector<uint64_t> ids = std::move(it->second);
  held_.erase(it);
  Job* job = jobs_.Find(job_id);
  if (!job || !job->active()) return;
  size_t released = 0;
  for (uint64_t id : ids)
    if (job->runtime(id).state == TaskState::kQueued) {
      queue_.Push(*job, id);
      ++released;
    }
  spdlog::info("job {}: map {} ready: {} render tasks queued", job_id, map_index, released);
  Touch(*job, fx);
}

SchedulerCounters Scheduler::counters() const {
  std::lock_guard lock(mu_);
  SchedulerCounters c = counters_;
  c.parked_polls = waiters_.size();
  for (const Job* job : jobs_.InSubmissionOrder()) c.tasks_in_memory += job->tasks().size();
  return c;
}

}  // namespace pf::server
