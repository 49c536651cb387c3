#include "server/scheduling/scheduler.h"

#include <spdlog/spdlog.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

// Released task lists at least this long are worth a malloc_trim (it walks the whole heap).
constexpr uint64_t kReturnMemoryAfterTasks = 1 << 16;

void ReturnFreedMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

v1::JobState ToProto(JobState s) {
  switch (s) {
    case JobState::kQueued:
      return v1::JOB_STATE_QUEUED;
    case JobState::kRunning:
      return v1::JOB_STATE_RUNNING;
    case JobState::kSucceeded:
      return v1::JOB_STATE_SUCCEEDED;
    case JobState::kFailed:
      return v1::JOB_STATE_FAILED;
    case JobState::kCancelled:
      return v1::JOB_STATE_CANCELLED;
  }
  return v1::JOB_STATE_UNSPECIFIED;
}

}  // namespace

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
                                   const std::string& holder, const std::string& call, Effects& fx) {
  spdlog::warn("job {} task {}: {} from worker {} refused: the lease is held by {}", job_id, task_id, call,
               limits::Quote(worker_id, limits::kMaxWorkerIdBytes), holder);
  fx.hijacks.push_back(
      {job_id, worker_id, task_id,
       call + " with the lease of task " + std::to_string(task_id) + ", held by another worker"});
}

void Scheduler::Touch(Job& job, Effects& fx) {
  fx.changed.insert(job.id());
  fx.persist = true;
}

// ---------------------------------------------------------------------------------------------
// Queue

void Scheduler::Enqueue(Job& job, uint64_t task_id, Effects& fx) {
  if (map_hook_ && !map_hook_->RenderTaskReady(job, job.task(task_id))) {
    held_[{job.id(), job.task(task_id).map_index}].push_back(task_id);
    Touch(job, fx);
    return;
  }
  queue_.Push(job, task_id);
  Touch(job, fx);
}

void Scheduler::Dequeue(Job& job, uint64_t task_id) {
  queue_.Remove(job, task_id);
}

void Scheduler::ServeWaiters(Effects& fx) {
  const double now = clock_.Now();
  for (auto it = waiters_.begin();
       it != waiters_.end() && (!queue_.empty() || map_hook_ || verification_.HasQueued());) {
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
  if (map_hook_) {
    MapTracingHook::JobFilter may_lease;
    if (failed_before)
      may_lease = [&](const std::string& job_id) {
        if (!health_.IsBlocklisted(job_id, worker)) return true;
        passed = true;
        return false;
      };
    if (std::optional<Lease> chunk = map_hook_->LeaseChunk(request, now, may_lease)) {
      chunk->worker_id = worker;
      return chunk;
    }
  }
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

// ---------------------------------------------------------------------------------------------
// Jobs

std::unique_ptr<Job> Scheduler::PrepareJob(JobConfig config) {
  // The expansion that creates this job's tasks, stored with its spec (recovery.cpp compares it).
  config.spec.mutable_plan()->set_expansion_version(PlanExpansionVersion(config.plan));
  config.spec.mutable_plan()->set_build(options_.build);  // whose workers render it (recovery.cpp)
  std::vector<TaskSpec> tasks = ScheduledTasks(config);
  auto shared = std::make_shared<const JobConfig>(std::move(config));
  std::pair<uint64_t, std::string> id;
  {
    std::lock_guard lock(mu_);
    id = jobs_.Allocate();
  }
  return std::make_unique<Job>(id.second, id.first, std::move(shared), std::move(tasks), clock_.UnixMillis());
}

void Scheduler::ReserveJobSeq(uint64_t seq) {
  std::lock_guard lock(mu_);
  jobs_.ReserveUpTo(seq);
}

void Scheduler::AddJob(std::unique_ptr<Job> job) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    Job& j = jobs_.Add(std::move(job));
    sources_[&j] = task_sources_(j.config());
    // Nobody else can reach the job yet: its accumulator may be read under this lock alone.
    const Accumulator* acc = j.accumulator_if_loaded();
    j.samples_merged = acc ? acc->samples_merged() : j.stored_samples_merged;
    if (j.active()) {
      Charge(j, +1);
      for (uint64_t id = 0; id < j.num_tasks(); ++id)
        if (j.runtime(id).state == TaskState::kQueued) Enqueue(j, id, fx);
      AddTasksFromSource(j, fx);  // recovery: the tasks the merged results had created
      const double now = clock_.Now();
      MaybeSucceed(j, now, fx);  // recovery: everything may already be merged
      ServeWaiters(fx);
    }
    fx.changed.insert(j.id());
  }
  Run(fx);
}

v1::JobStatus Scheduler::BuildStatus(Job& job, double now) {
  v1::JobStatus s;
  s.set_job_id(job.id());
  *s.mutable_spec() = job.config().spec;
  s.set_state(ToProto(job.state()));
  s.set_failure_reason(job.failure_reason());
  const uint64_t cancelled = job.count(TaskState::kCancelled);
  const uint64_t done = job.count(TaskState::kDone);
  const uint64_t total = job.num_tasks() - (job.active() ? cancelled : 0);
  s.set_tasks_total(total);
  s.set_tasks_done(done);
  s.set_tasks_running(job.count(TaskState::kLeased));
  s.set_tasks_queued(job.count(TaskState::kQueued));
  s.set_tasks_cancelled(cancelled);
  const double elapsed = job.ElapsedSeconds(now);
  s.set_elapsed_seconds(elapsed);
  s.set_rounds_done(job.rounds_done());
  s.set_submitted_unix_ms(job.submitted_unix_ms());
  s.set_samples_merged(job.samples_merged);
  if (!job.accumulator_if_loaded()) job.noise_cache = job.stored_noise_rms;
  // The estimate as last refreshed (RefreshNoise, outside this lock: it is an O(pixels) pass).
  s.set_estimated_noise_rms(job.noise_cache);
  s.set_storage_error(job.results_storage_error.empty() ? job.rows_storage_error
                      : job.rows_storage_error.empty()
                          ? job.results_storage_error
                          : job.results_storage_error + "; " + job.rows_storage_error);
  s.set_paused_for_storage(job.paused_for_storage);
  // Progress and ETA count work (Job::task_work: tasks, or the hierarchical plan's pixel samples and
  // maps), including what the plan's task source expects to create (its localization tasks).
  // As of the last merge (the hierarchical source reads the accumulator, guarded by image_mu).
  const double work_to_create = job.active() && !job.stopping ? double(job.work_to_create) : 0.0;
  const double work_done = double(job.work(TaskState::kDone));
  const double work_total =
      double(job.work(TaskState::kDone) + job.work(TaskState::kLeased) + job.work(TaskState::kQueued)) +
      (job.active() ? 0.0 : double(job.work(TaskState::kCancelled))) + work_to_create;
  job.progress_shown = std::max(job.progress_shown, job.state() == JobState::kSucceeded ? 1.0
                                                    : work_total > 0 ? work_done / work_total
                                                                     : 0.0);
  s.set_progress(job.progress_shown);
  // ETA from recent throughput (server/jobs/eta_estimator.h says why); until two tasks are
  // merged, from the average rate of (merged + in-progress fractions) so far.
  double eta = -1;
  if (!job.active()) {
    eta = 0;
  } else {
    const double done_eff = work_done + leases_.ProgressOf(job);
    const double running = double(job.work(TaskState::kLeased));
    const double remaining = job.stopping ? running : work_total - done_eff;
    double average = -1;
    if (done_eff > 0 && elapsed > 0) average = std::max(0.0, elapsed * remaining / done_eff);
    eta = job.eta.Eta(now, job.stopping ? running : work_total - work_done, running, average);
    const double budget = job.config().stop.time_budget_seconds;
    if (budget > 0 && eta >= 0) eta = std::min(eta, std::max(0.0, budget - elapsed));
  }
  s.set_eta_seconds(eta);
  s.set_verifications_pending(verification_.Pending(job));
  s.set_results_verified(verification_.Verified(job));
  for (const auto& [worker, entry] : health_.BlocklistOf(job.id())) {
    v1::BlocklistedWorker* b = s.add_blocklisted_workers();
    b->set_worker_id(worker);
    b->set_failed_attempts(entry.failed_attempts);
    b->set_last_error(entry.last_error);
  }
  return s;
}

Job& Scheduler::FindJob(const std::string& job_id) {
  std::lock_guard lock(mu_);
  return jobs_.Get(job_id);  // jobs are never removed: the reference outlives the lock
}

void Scheduler::RefreshNoise(Job& job) {
  // Holding image_mu, every committed merge is in the accumulator (Complete commits and adds
  // within one hold), so the estimate belongs to the merge_seq read here.
  std::lock_guard image(job.image_mu);
  const Accumulator* acc = job.accumulator_if_loaded();
  if (!acc) return;
  {
    std::lock_guard lock(mu_);
    // Refreshed when stale and: the interval passed, another round or map became complete (the
    // moments the estimate changes most), or the job is over.
    const bool stale = job.noise_checked_seq != job.merge_seq();
    if (!stale || !(clock_.Now() - job.noise_checked_at >= options_.noise_check_interval ||
                    job.full_coverage() != job.noise_checked_coverage || !job.active()))
      return;
  }
  const double noise = acc->EstimatedNoiseRms();
  std::lock_guard lock(mu_);
  job.SetNoise(noise, clock_.Now());
}

v1::JobStatus Scheduler::Status(const std::string& job_id) {
  Job& job = FindJob(job_id);
  RefreshNoise(job);
  std::lock_guard lock(mu_);
  return BuildStatus(job, clock_.Now());
}

void Scheduler::RefreshNoiseOfAll(bool include_finished) {
  std::vector<Job*> jobs;
  {
    std::lock_guard lock(mu_);
    for (Job* job : jobs_.InSubmissionOrder())
      if ((include_finished || job->active()) && job->accumulator_if_loaded()) jobs.push_back(job);
  }
  for (Job* job : jobs) RefreshNoise(*job);
}

std::vector<v1::JobStatus> Scheduler::List(bool include_finished) {
  RefreshNoiseOfAll(include_finished);
  std::lock_guard lock(mu_);
  const double now = clock_.Now();
  std::vector<v1::JobStatus> out;
  for (Job* job : jobs_.InSubmissionOrder())
    if (include_finished || job->active()) out.push_back(BuildStatus(*job, now));
  return out;
}

Scheduler::JobPage Scheduler::ListPage(bool include_finished, uint64_t after_seq, size_t limit) {
  RefreshNoiseOfAll(include_finished);
  std::lock_guard lock(mu_);
  const double now = clock_.Now();
  JobPage page;
  for (Job* job : jobs_.InSubmissionOrder()) {
    if (job->seq() <= after_seq || !(include_finished || job->active())) continue;
    if (page.jobs.size() == limit) {
      page.more = true;
      break;
    }
    page.jobs.push_back(BuildStatus(*job, now));
    page.last_seq = job->seq();
  }
  return page;
}

v1::JobStatus Scheduler::Cancel(const std::string& job_id) {
  Effects fx;
  Job& job = FindJob(job_id);
  {
    std::lock_guard lock(mu_);
    if (job.active()) {
      FinishJob(job, JobState::kCancelled, "", clock_.Now(), fx);
      spdlog::info("job {}: cancelled", job.id());
    }
  }
  Run(fx);
  RefreshNoise(job);  // the final estimate
  std::lock_guard lock(mu_);
  return BuildStatus(job, clock_.Now());
}

JobSnapshot Scheduler::Snapshot(const std::string& job_id, bool with_image) {
  Job& job = FindJob(job_id);
  JobSnapshot snap;
  if (!with_image) {
    RefreshNoise(job);
    std::lock_guard lock(mu_);
    snap.status = BuildStatus(job, clock_.Now());
    return snap;
  }
  // The image is resolved (O(pixels)) under the job's image_mu only; the status is built under
  // the scheduler's lock inside that hold, so both describe the same merges.
  std::lock_guard image(job.image_mu);
  if (const Accumulator* acc = job.accumulator_if_loaded()) snap.image = ResolveSnapshot(job.id(), *acc);
  std::lock_guard lock(mu_);
  const double now = clock_.Now();
  if (snap.image)
    job.SetNoise(snap.image->noise_rms, now);  // the status says what the image says
  else {
    snap.checkpoint_path = job.checkpoint_path;
    snap.checkpoint_seal = job.checkpoint_seal;
  }
  snap.status = BuildStatus(job, now);
  return snap;
}

void Scheduler::FinishJob(Job& job, JobState state, const std::string& reason, double now, Effects& fx) {
  if (job.active()) Charge(job, -1);
  for (uint64_t id = 0; id < job.num_tasks(); ++id) {
    TaskRuntime& rt = job.runtime(id);
    if (rt.state == TaskState::kQueued) {
      Dequeue(job, id);
      job.CancelAsJobEnds(id);
    } else if (rt.state == TaskState::kLeased) {
      leases_.Erase(rt.lease_id);
      job.CancelAsJobEnds(id);
      activity_.TaskEvent(job.id(), "cancelled", id, rt.attempts, rt.worker_id, "the job ended while leased");
    }
  }
  queue_.Unhold(job);  // nothing of it is queued any more: forget that it was held
  if (state == JobState::kSucceeded && job.state() == JobState::kQueued)
    job.TransitionTo(JobState::kRunning, now);
  job.TransitionTo(state, now, reason);
  health_.JobEnded(job.id());
  verification_.DropJob(job, /*ended=*/true);
  // The final noise estimate is an O(pixels) pass: computed off this lock by the next status,
  // snapshot or persist (RefreshNoise, CollectPersistBatch), whichever comes first.
  Touch(job, fx);
}

void Scheduler::Charge(Job& job, int sign) {
  if (sign > 0) {
    job.charged_tasks = job.num_tasks();
    job.charged_pixels = uint64_t(job.config().camera.width) * uint64_t(job.config().camera.height);
    ++load_.jobs;
    load_.tasks += job.charged_tasks;
    load_.pixels += job.charged_pixels;
    if (!job.client.empty()) ++client_jobs_[job.client];
    return;
  }
  // The job ends; its tasks and pixels count until they are released (ReleaseFinishedTasks).
  --load_.jobs;
  if (auto it = client_jobs_.find(job.client); it != client_jobs_.end() && --it->second == 0)
    client_jobs_.erase(it);
}

ActiveLoad Scheduler::Load(const std::string& client) const {
  std::lock_guard lock(mu_);
  ActiveLoad load = load_;
  auto it = client_jobs_.find(client);
  load.client_jobs = it == client_jobs_.end() ? 0 : it->second;
  return load;
}

void Scheduler::MaybeSucceed(Job& job, double now, Effects& fx) {
  if (!job.active() || job.count(TaskState::kQueued) > 0 || job.count(TaskState::kLeased) > 0) return;
  if (verification_.Pending(job) > 0) {  // not before its results are verified
    RefereeIfNoVerifierLocked(job, now, fx);
    return;
  }
  FinishJob(job, JobState::kSucceeded, "", now, fx);
  spdlog::info("job {}: succeeded: {} of {} tasks merged in {:.3f} s{}", job.id(),
               job.count(TaskState::kDone), job.num_tasks(), job.ElapsedSeconds(now),
               job.stopping ? " (time budget)" : "");
}

void Scheduler::AddTasksFromSource(Job& job, Effects& fx) {
  if (!job.active() || job.stopping) return;
  auto it = sources_.find(&job);
  if (it == sources_.end()) return;
  // Called with the job's image_mu held (or before anyone else can reach the job): the
  // hierarchical source reads the accumulator.
  const std::vector<TaskSpec> added = it->second->TasksAfterMerge(job);
  if (!added.empty()) job.AppendTasks(added);
  job.work_to_create = it->second->WorkToCreate(job);
  if (added.empty()) return;
  for (const TaskSpec& t : added) Enqueue(job, t.task_id, fx);
  spdlog::info("job {}: {} tasks added from the merged results (ids {}..{})", job.id(), added.size(),
               added.front().task_id, added.back().task_id);
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
  Job& job = *entry->job;
  const uint64_t task_id = entry->task_id;
  // A pinned lease's result arrived in time and is being merged: it decides the attempt.
  if (now >= job.runtime(task_id).lease_deadline && !job.runtime(task_id).merging) {
    ExpireLease(job, task_id, now, fx);
    return nullptr;
  }
  return entry;
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
      TaskRuntime& rt = ref->job->runtime(ref->task_id);
      if (rt.worker_id != worker_id) {
        // A lease id that reached another worker does not keep the task from being re-run.
        result.not_holder = true;
        NotTheHolderLocked(ref->job->id(), ref->task_id, worker_id, rt.worker_id, "ExtendLease", fx);
      } else {
        rt.lease_deadline = now + options_.lease_seconds;
        rt.progress = std::isfinite(progress) ? std::clamp(progress, 0.0, 1.0) : 0.0;
        result = {true, options_.lease_seconds};
      }
    }
  }
  Run(fx);
  return result;
}

CompleteResult Scheduler::Complete(const std::string& lease_id, const std::string& worker_id,
                                   std::span<const float> rgb_sums, RadiancePart part) {
  const bool verify = verification_.enabled();
  if (verify && IsVerificationLease(lease_id))
    return CompleteVerification(lease_id, worker_id, rgb_sums, part);
  Effects fx;
  CompleteResult result;
  // 1. Claim (global lock, O(1)): the lease must be live; it is pinned (TaskRuntime::merging) so
  //    that it neither expires nor takes a second result while this one is checked.
  Job* job = nullptr;
  uint64_t task_id = 0;
  TaskSpec task;                   // a copy: the job's task vector may grow (AppendTasks) meanwhile
  bool needs_accumulator = false;  // read under the lock: the pointer changes under both locks
  std::vector<double> references;  // verification: the outlier test's (result_verification.h)
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    HeardLocked(worker_id, now);
    LeaseTable::Entry* ref = FindLiveLease(lease_id, now, fx);
    if (ref && ref->job->runtime(ref->task_id).worker_id != worker_id) {
      // Another worker's result for this lease is not the holder's: nothing is merged, and the
      // holder's lease stays as it is.
      result.status = CompleteStatus::kNotHolder;
      result.reason = "the lease is held by another worker";
      NotTheHolderLocked(ref->job->id(), ref->task_id, worker_id, ref->job->runtime(ref->task_id).worker_id,
                         "CompleteTask", fx);
    } else if (!ref || ref->job->runtime(ref->task_id).merging) {
      ++counters_.ignored;
      result.reason =
          ref ? "a result for this lease is already being merged" : "unknown, expired or finished lease";
      spdlog::info("result for lease {} ignored: {}", limits::Quote(lease_id, limits::kMaxIdBytes),
                   result.reason);
    } else {
      job = ref->job;
      task_id = ref->task_id;
      task = job->task(task_id);
      job->runtime(task_id).merging = true;
      needs_accumulator = !job->accumulator_if_loaded();
      if (verify && verification_.options().outliers)
        references = verification_.References(*job, ResultGroup(task));
    }
  }
  if (!job) {
    Run(fx);
    return result;
  }
  result.job_id = job->id();
  result.task_id = task_id;
  // Until the commit, an exception (an allocation failing in the check, a hook in a test) must
  // not leave the lease pinned: unpinned, it expires or takes a result again as any lease would.
  struct Unpin {
    Scheduler* self;
    Job* job;
    uint64_t task_id;
    std::string lease_id;
    bool armed = true;
    ~Unpin() {
      if (!armed) return;
      {
        std::lock_guard lock(self->mu_);
        if (job->has_runtime(task_id) && job->runtime(task_id).lease_id == lease_id)
          job->runtime(task_id).merging = false;  // as the commit does
      }
      try {  // a destructor must not throw, even if logging cannot allocate
        spdlog::error(
            "job {} task {}: the result for lease {} could not be checked (exception); the lease "
            "stays live",
            job->id(), task_id, limits::Quote(lease_id, limits::kMaxIdBytes));
      } catch (...) {
      }
    }
  } unpin{this, job, task_id, lease_id};

  // 2. Check (no lock, O(pixels)): the one check of a worker's result (the edge), and the pixel
  //    indices the merge needs. The configuration is immutable.
  const JobConfig& config = job->config();
  const int width = config.camera.width, height = config.camera.height;
  CheckedResult checked = ResultMerger::Check(task, width, height, rgb_sums, config.max_sample_radiance);
  if (part != task.part && checked.valid) {
    // Hierarchical plan with part indirect (radiance_part.h): a worker that does not know
    // Task.part renders everything, and its sums would count emission and direct light twice.
    const auto name = [](RadiancePart p) {
      return p == RadiancePart::kMapped ? "mapped" : p == RadiancePart::kUnmapped ? "unmapped" : "all";
    };
    checked = CheckedResult{std::nullopt,
                            std::string("part: the result is of part ") + name(part) + ", the task's is " +
                                name(task.part) + " (a worker older than Task.part? upgrade it)",
                            ResultCheck::Verdict::kInvalid};
  }
  std::string digest;  // of a result above the bound that is valid apart from the bound
  if (checked.verdict == ResultCheck::Verdict::kImplausible) {
    CheckedResult unbounded = ResultMerger::Check(task, width, height, rgb_sums);
    if (unbounded.valid) {
      digest = ResultMerger::Digest(rgb_sums);
      checked.valid = unbounded.valid;  // merged only once confirmed (below)
    } else {
      checked = std::move(unbounded);  // invalid anyway
    }
  }
  std::string problem = checked.problem;
  std::vector<uint32_t> pixels;
  if (checked.valid) {
    try {
      pixels = merger_.PixelsOfTask(task, width, height);
      const uint64_t image_pixels = uint64_t(width) * uint64_t(height);
      for (uint32_t p : pixels)  // checked here: after the commit, the add must not fail
        if (p >= image_pixels) throw InputError("pixels: index " + std::to_string(p) + " outside the image");
    } catch (const InputError& e) {
      problem = e.what();  // the task's own pixel set is out of range: a coordinator bug
      checked = CheckedResult{std::nullopt, problem, ResultCheck::Verdict::kInvalid};
    }
  }
  // Verification: chosen now, when the result arrives (the CSPRNG, or the outlier test); only a
  // chosen result's digest is computed.
  ResultSummary summary;
  std::string verify_reason;
  if (verify && checked.valid) {
    summary = SummarizeResult(task, rgb_sums);
    const OutlierScore score = ScoreAgainst(summary.midmean, references);
    if (verification_.options().outliers && score.outlier)
      verify_reason = "outlier: z = " + std::to_string(score.z);
    else if (verification_.ChooseAtRandom())
      verify_reason = "sampled";
    if (!verify_reason.empty() && digest.empty()) digest = ResultMerger::Digest(rgb_sums);
  }
  // The job's first merge allocates its accumulator (O(pixels)) here, before the commit: once a
  // task is recorded as merged nothing may fail, or its samples would be lost.
  std::unique_ptr<Accumulator> fresh;
  if (checked.valid && needs_accumulator) fresh = std::make_unique<Accumulator>(config.plan, width, height);
  if (before_commit_for_test_) before_commit_for_test_(lease_id);
  unpin.armed = false;  // from here on the commit below unpins

  // 3. Commit (image_mu, then the global lock for O(1) bookkeeping), add (image_mu only,
  //    O(pixels)), then the rules that follow a merge. Commit and add happen within one hold of
  //    image_mu, so whoever holds it sees an accumulator that agrees with the job's merged tasks.
  std::unique_lock image(job->image_mu);
  bool merged = false;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    TaskRuntime gone;  // a restart took the task away (an appended task of a dynamic plan)
    TaskRuntime& rt = job->has_runtime(task_id) ? job->runtime(task_id) : gone;
    if (rt.lease_id == lease_id) rt.merging = false;  // not a new lease of a task a restart re-created
    const bool convicted = std::find(job->convicted_workers.begin(), job->convicted_workers.end(),
                                     worker_id) != job->convicted_workers.end();
    if (convicted && rt.state == TaskState::kLeased && rt.lease_id == lease_id) {
      // Convicted while this result was checked (its lease was pinned, so not revoked): never
      // merged; the task goes back to the queue.
      ++counters_.ignored;
      result.reason = "its worker was convicted while the result was checked";
      spdlog::info("job {} task {}: result ignored: {}", job->id(), task_id, result.reason);
      leases_.Erase(lease_id);
      job->SetTaskState(task_id, TaskState::kQueued);
      Enqueue(*job, task_id, fx);
    } else if (rt.state != TaskState::kLeased || rt.lease_id != lease_id) {
      // Only a job's end (cancel, failure, stop rule) or its restart (ConvictWorker) takes a
      // pinned lease away.
      ++counters_.ignored;
      result.reason = "the job ended while the result was checked";
      spdlog::info("job {} task {}: result ignored: {}", job->id(), task_id, result.reason);
    } else {
      if (checked.verdict == ResultCheck::Verdict::kImplausible) {
        // Merged (valid without the bound) once a second worker's bytes are identical.
        problem = ConfirmImplausible(*job, task_id, digest, ResultCheck{checked.verdict, checked.problem});
      }
      if (!problem.empty()) {
        ++counters_.rejected;
        result.status = CompleteStatus::kRejected;
        result.reason = problem;
        spdlog::warn("job {} task {}: result of attempt {} rejected: {}", job->id(), task_id, rt.attempts,
                     problem);
        activity_.TaskEvent(job->id(), "rejected", task_id, rt.attempts, rt.worker_id, problem);
        FailAttempt(*job, task_id, "rejected result: " + problem, true, now, fx);
      } else {
        ++counters_.merged;
        leases_.Erase(lease_id);
        job->RecordMerge(task_id);
        job->eta.RecordCompletion(now, double(job->task_work(task_id)));
        result.status = CompleteStatus::kMerged;
        result.merge_seq = job->merge_seq();
        result.epoch = job->epoch();
        result.worker_id = rt.worker_id;
        activity_.TaskEvent(job->id(), "merged", task_id, rt.attempts, result.worker_id);
        spdlog::info("job {} task {}: merged (attempt {}, worker {}; {}/{} done)", job->id(), task_id,
                     rt.attempts, rt.worker_id, job->count(TaskState::kDone), job->num_tasks());
        Touch(*job, fx);
        merged = true;
        if (verify) {
          verification_.RecordMean(*job, summary.group, summary.midmean);
          if (!verify_reason.empty())
            AddVerificationLocked(*job, task_id, result.worker_id, digest, verify_reason, fx);
        }
      }
    }
  }
  if (merged) {
    if (!job->accumulator_if_loaded()) {
      // Allocated before the commit (above); the pointer changes under both locks. A concurrent
      // first merge may have installed one meanwhile: then ours is dropped. The fallback covers a
      // claim that saw one loaded (it is released only for finished jobs, whose results the
      // commit refuses).
      if (!fresh) fresh = std::make_unique<Accumulator>(config.plan, width, height);  // not reached
      std::lock_guard lock(mu_);
      job->set_accumulator(std::move(fresh));
    }
    Accumulator& acc = job->accumulator();
    ResultMerger::Merge(*checked.valid, pixels, acc);
    bool noise_due = false;
    {
      std::lock_guard lock(mu_);
      job->samples_merged = acc.samples_merged();
      noise_due = NoiseTargetDue(*job, clock_.Now(), options_.noise_check_interval);
    }
    const double noise = noise_due ? acc.EstimatedNoiseRms() : -1;  // O(pixels), off the lock
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    if (noise_due && job->active()) {
      job->noise_target_checked_at = now;
      job->SetNoise(noise, now);
      if (NoiseTargetMet(*job)) {
        spdlog::info("job {}: estimated noise {:.4g} <= target {:.4g} after {} tasks: done", job->id(),
                     job->noise_cache, config.stop.target_noise_rms, job->count(TaskState::kDone));
        SucceedOnTarget(*job, now, fx);
      }
    }
    AddTasksFromSource(*job, fx);
    MaybeSucceed(*job, now, fx);
    ServeWaiters(fx);
  }
  image.unlock();
  Run(fx);
  return result;
}

void Scheduler::SetBeforeCommitHookForTest(std::function<void(const std::string& lease_id)> hook) {
  before_commit_for_test_ = std::move(hook);
}

std::string Scheduler::ConfirmImplausible(Job& job, uint64_t task_id, const std::string& digest,
                                          const ResultCheck& check) {
  // Above the bound is not proof of a fault (estimator tails are unbounded, docs/security.md
  // "Results"), and a rejection of an honest result would repeat on every retry (rendering is
  // deterministic) until the job fails. So: not merged, re-run; merged when a different worker
  // delivers the same bytes.
  TaskRuntime& rt = job.runtime(task_id);
  if (!rt.implausible_digest.empty() && digest == rt.implausible_digest &&
      rt.worker_id != rt.implausible_worker) {
    spdlog::warn(
        "job {} task {}: result above the bound reproduced bit for bit by worker {} (first from {}): merged "
        "({})",
        job.id(), task_id, rt.worker_id, rt.implausible_worker, check.reason);
    activity_.TaskEvent(job.id(), "confirmed", task_id, rt.attempts, rt.worker_id,
                        "reproduced a result above the bound first sent by " + rt.implausible_worker);
    return "";
  }
  rt.implausible_digest = digest;
  rt.implausible_worker = rt.worker_id;
  return check.reason + "; re-run, merged only if another worker reproduces it exactly";
}

void Scheduler::FailAttempt(Job& job, uint64_t task_id, const std::string& reason, bool retryable, double now,
                            Effects& fx) {
  TaskRuntime& rt = job.runtime(task_id);
  leases_.Erase(rt.lease_id);
  ++rt.failures;
  ++counters_.failed_attempts;
  rt.last_error = reason;
  const uint32_t attempt = rt.attempts;
  const std::string worker = rt.worker_id;
  if (worker.empty())
    ++rt.unattributed_failures;
  else if (std::find(rt.failed_workers.begin(), rt.failed_workers.end(), worker) == rt.failed_workers.end())
    rt.failed_workers.push_back(worker);
  Touch(job, fx);
  if (!job.active()) return;
  const bool blocklisted = CountFailure(job, worker, task_id, attempt, reason, now);
  if (job.stopping && job.task(task_id).part != RadiancePart::kUnmapped) {  // see CheckTimeBudget
    job.SetTaskState(task_id, TaskState::kCancelled);
    spdlog::info("job {} task {}: attempt {} ended ({}); not retried (time budget reached)", job.id(),
                 task_id, attempt, reason);
    MaybeSucceed(job, now, fx);
    return;
  }
  // A task fails its job on failures on max_attempts distinct workers, not on max_attempts
  // failures: one bad worker must not use up the attempts while good workers are busy. What bounds
  // the retries of a task every worker fails is the blocklist: each worker fails it at most
  // blocklist_failures times, then, with no worker left, the job fails.
  const std::string failed =
      "task " + std::to_string(task_id) + " attempt " + std::to_string(attempt) + " failed: " + reason;
  const uint32_t distinct = uint32_t(rt.failed_workers.size()) + rt.unattributed_failures;
  std::string why;
  if (!retryable) {
    why = failed + " (not retryable)";
  } else if (distinct >= options_.max_attempts) {
    std::string names;
    for (const std::string& w : rt.failed_workers) names += (names.empty() ? "" : ", ") + w;
    why = failed + "; gave up after " + std::to_string(rt.failures) + " failed attempts on " +
          std::to_string(distinct) + " workers (" + names +
          (rt.unattributed_failures ? (names.empty() ? "" : "; ") + std::to_string(rt.unattributed_failures) +
                                          " not attributed to a worker"
                                    : "") +
          ")";
  } else if (blocklisted) {
    if (const std::string none = NoWorkerLeft(job); !none.empty())
      why = failed + "; gave up after " + std::to_string(rt.failures) + " failed attempts: " + none;
  }
  if (!why.empty()) {
    job.SetTaskState(task_id, TaskState::kCancelled);
    FinishJob(job, JobState::kFailed, why, now, fx);
    spdlog::error("job {}: failed: {}", job.id(), why);
    return;
  }
  job.SetTaskState(task_id, TaskState::kQueued);
  Enqueue(job, task_id, fx);
  spdlog::warn("job {} task {}: attempt {} failed ({}); re-queued (failed on {} of {} workers)", job.id(),
               task_id, attempt, reason, distinct, options_.max_attempts);
  ServeWaiters(fx);
}

// ---------------------------------------------------------------------------------------------
// Worker health (worker_health.h)

void Scheduler::PolledLocked(const std::string& worker_id, double now) {
  if (!health_.Polled(worker_id, now)) return;
  activity_.WorkerLost(worker_id, false);
  spdlog::info("worker {}: live again (it called)", limits::Quote(worker_id, limits::kMaxWorkerIdBytes));
}

void Scheduler::HeardLocked(const std::string& worker_id, double now) {
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

void Scheduler::Heard(const std::string& worker_id) {
  std::lock_guard lock(mu_);
  HeardLocked(worker_id, clock_.Now());
}

void Scheduler::PieceAttemptFailed(const std::string& job_id, const std::string& worker_id, uint32_t piece,
                                   uint32_t attempt, const std::string& kind, const std::string& reason) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    if (Job* job = jobs_.Find(job_id)) {
      activity_.TaskEvent(job_id, kind, piece, attempt, worker_id, reason);
      if (job->active() && CountFailure(*job, worker_id, piece, attempt, reason, now)) {
        if (const std::string none = NoWorkerLeft(*job); !none.empty()) {
          const std::string why = "map piece " + std::to_string(piece) + " attempt " +
                                  std::to_string(attempt) + " failed: " + reason + "; gave up: " + none;
          FinishJob(*job, JobState::kFailed, why, now, fx);
          spdlog::error("job {}: failed: {}", job_id, why);
        }
      }
    }
  }
  Run(fx);
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
      const TaskRuntime& rt = ref->job->runtime(ref->task_id);
      if (rt.merging) {
        // The result it sent is being merged; that decides the attempt (kUnknownLease: the lease
        // is as good as finished).
        spdlog::info("job {} task {}: FailTask ignored: its result is being merged", ref->job->id(),
                     ref->task_id);
      } else if (rt.worker_id != worker_id) {
        // A lease id that reached another worker (a log, a copied command line) does not let it
        // end the task — with retryable = false, the whole job.
        outcome = FailOutcome::kNotHolder;
        NotTheHolderLocked(ref->job->id(), ref->task_id, worker_id, rt.worker_id, "FailTask", fx);
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
    if (ReturnVerificationLocked(lease_id, fx)) {
      ServeWaiters(fx);
    } else {
      LeaseTable::Entry* entry = leases_.Find(lease_id);
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
  return job ? job->checkpoint_written_seq : 0;
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

// ---------------------------------------------------------------------------------------------
// Time

void Scheduler::Tick() {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    // A long poll still open is a call in progress: a worker waiting for work is not silent.
    for (const auto& [id, waiter] : waiters_) PolledLocked(waiter.request.worker_id, now);
    for (const std::string& id : leases_.Expired(now)) {
      LeaseTable::Entry* entry = leases_.Find(id);
      if (!entry) continue;  // its job ended meanwhile
      Job& job = *entry->job;
      const uint64_t task_id = entry->task_id;
      if (job.runtime(task_id).merging) continue;  // its result arrived in time (Complete)
      ExpireLease(job, task_id, now, fx);
    }
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
// Persistence

std::vector<Checkpoint> Scheduler::CollectCheckpoints(bool due) {
  std::vector<Checkpoint> out;
  // One job at a time under its image_mu (the global lock only for O(1) bookkeeping): free what
  // is on disk, the final noise estimate of a finished job, checkpoints.
  std::vector<Job*> loaded;
  {
    std::lock_guard lock(mu_);
    for (Job* job : jobs_.InSubmissionOrder())
      if (job->accumulator_if_loaded()) loaded.push_back(job);
  }
  for (Job* job : loaded) {
    std::lock_guard image(job->image_mu);
    bool final_noise = false, checkpoint = false;
    Checkpoint cp;
    {
      std::lock_guard lock(mu_);
      if (!job->accumulator_if_loaded()) continue;
      final_noise = !job->active() && job->noise_checked_seq != job->merge_seq();
      checkpoint = job->merge_seq() > job->checkpoint_collected_seq &&
                   (due || !job->active() || job->checkpoint_retry);
      if (checkpoint) {
        cp.job_id = job->id();
        cp.merge_seq = job->merge_seq();
        cp.epoch = job->epoch();
        // With the epoch, so that a restart's checkpoint stored without its row brings back who
        // was convicted as well (recovery.cpp).
        cp.convicted = job->convicted_workers;
        cp.merged_task_ids = job->MergedTaskIds();
        job->checkpoint_collected_seq = job->merge_seq();
        job->checkpoint_retry = false;
      }
    }
    const Accumulator& acc = *job->accumulator_if_loaded();
    if (final_noise) {
      const double noise = acc.EstimatedNoiseRms();
      std::lock_guard lock(mu_);
      job->SetNoise(noise, clock_.Now());
      job->row_dirty = true;
    }
    if (checkpoint) {
      cp.accumulator = acc.Serialize();
      out.push_back(std::move(cp));
    }
    // A job that ended after its last checkpoint was stored (e.g. cancelled) frees its image now.
    std::lock_guard lock(mu_);
    if (!job->active()) job->ReleaseAccumulator(job->checkpoint_path);
  }
  return out;
}

void Scheduler::CheckpointStored(const Checkpoint& cp, const CheckpointSeal& seal, const std::string& path) {
  Job* job = nullptr;
  {
    std::lock_guard lock(mu_);
    job = jobs_.Find(cp.job_id);
  }
  if (!job) return;
  Effects fx;
  {
    std::lock_guard image(job->image_mu);  // freeing the accumulator changes it
    std::lock_guard lock(mu_);
    if (cp.merge_seq < job->checkpoint_written_seq) return;
    job->checkpoint_written_seq = cp.merge_seq;
    job->checkpoint_seal = seal;
    job->checkpoint_path = path;
    job->row_dirty = true;  // the row carries the seal
    for (uint64_t id : cp.merged_task_ids)
      if (id < job->num_tasks()) job->MarkStored(id);
    if (!job->results_storage_error.empty()) fx.changed.insert(job->id());
    job->results_storage_error.clear();
    if (job->paused_for_storage) {
      job->paused_for_storage = false;
      spdlog::info("job {}: its results are stored again", job->id());
    }
    if (job->restart_checkpoint_seq != 0 && cp.merge_seq >= job->restart_checkpoint_seq) {
      job->restart_checkpoint_seq = 0;
      if (!job->restart_pending() && job->active()) job->RestartClock(clock_.Now());
    }
    if (!job->paused_for_storage && !job->restart_pending() && queue_.Unhold(*job)) {
      spdlog::info("job {}: resumed: its results can be stored{}", job->id(),
                   job->epoch() > 0 ? " and its restart is stored" : "");
      ServeWaiters(fx);
    }
    job->ReleaseAccumulator(path);  // a finished job's image now lives on disk only
  }
  Run(fx);
}

void Scheduler::CheckpointNotStored(const std::string& job_id, uint64_t merge_seq,
                                    const std::string& reason) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    Job* job = jobs_.Find(job_id);
    if (!job) return;
    if (job->checkpoint_collected_seq == merge_seq)
      job->checkpoint_collected_seq = job->checkpoint_written_seq;
    job->checkpoint_retry = true;
    job->results_storage_error = "checkpoint not stored: " + reason;
    fx.changed.insert(job->id());  // no persist wake: the persister retries on its own timer
  }
  Run(fx);
}

void Scheduler::ResultsJournaled(const std::string& job_id, std::span<const uint64_t> task_ids) {
  std::lock_guard lock(mu_);
  Job* job = jobs_.Find(job_id);
  if (!job) return;
  for (uint64_t id : task_ids)
    if (id < job->num_tasks()) job->MarkStored(id);
}

void Scheduler::ResultsNotStored(const std::string& job_id, const std::string& reason) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    Job* job = jobs_.Find(job_id);
    if (!job) return;
    job->results_storage_error = "results not stored: " + reason;
    job->checkpoint_retry = true;
    if (job->active() && !job->paused_for_storage) {
      job->paused_for_storage = true;
      queue_.Hold(*job);
      spdlog::error("job {}: paused: its results cannot be stored ({}); no new leases until they can",
                    job->id(), reason);
    }
    fx.changed.insert(job->id());
  }
  Run(fx);
}

void Scheduler::ForceCheckpoint(const std::string& job_id) {
  std::lock_guard lock(mu_);
  if (Job* job = jobs_.Find(job_id)) job->checkpoint_retry = true;
}

RowBatch Scheduler::CollectRows() {
  uint64_t released = 0;
  RowBatch batch = CollectRowsLocked(&released);
  // A released task list is mostly small blocks (the queue's tree nodes, its strings), which
  // malloc keeps for reuse: a cancelled 2^20-task job left ~100 MiB resident. Given back to the
  // system off the lock.
  if (released >= kReturnMemoryAfterTasks) ReturnFreedMemory();
  return batch;
}

RowBatch Scheduler::CollectRowsLocked(uint64_t* released) {
  RowBatch batch;
  std::lock_guard lock(mu_);
  for (Job* job : jobs_.InSubmissionOrder()) {
    // A finished job's final row waits for its final checkpoint to be stored, and for its final
    // noise estimate (docs/farm.md "Durability", D2). Its transition woke the persister.
    const bool held_back =
        !job->active() && (job->merge_seq() > job->checkpoint_written_seq ||
                           (job->accumulator_if_loaded() && job->noise_checked_seq != job->merge_seq()));
    if (job->row_dirty && !held_back) {
      JobRow row;
      row.job_id = job->id();
      row.seq = job->seq();
      row.spec = job->config().spec.SerializeAsString();
      row.state = job->state();
      row.failure_reason = job->failure_reason();
      row.submitted_unix_ms = job->submitted_unix_ms();
      row.elapsed_seconds = job->ElapsedSeconds(clock_.Now());
      row.samples_merged = job->samples_merged;
      row.noise_rms = job->accumulator_if_loaded() ? job->noise_cache : job->stored_noise_rms;
      row.checkpoint = job->checkpoint_seal;
      row.epoch = job->epoch();
      for (const std::string& w : job->convicted_workers)
        row.convicted += (row.convicted.empty() ? "" : "\n") + w;
      batch.jobs.push_back(std::move(row));
      job->row_dirty = false;
    }
    // A finished job whose task rows (from earlier flushes, one flush at a time) and final
    // checkpoint are stored needs its tasks no more (docs/farm.md "Coordinator memory").
    if (!job->active() && !job->tasks_released() && job->dirty_tasks.empty() &&
        job->merge_seq() == job->checkpoint_written_seq)
      *released += ReleaseFinishedTasks(*job);
    // A DONE row names a stored result (D2): a merged task whose result is not on disk yet waits.
    for (auto it = job->dirty_tasks.begin(); it != job->dirty_tasks.end();) {
      const TaskRuntime& rt = job->runtime(*it);
      if (rt.state == TaskState::kDone && !rt.stored) {
        ++it;
        continue;
      }
      batch.tasks.push_back({job->id(), *it, rt.state, rt.attempts, rt.failures, rt.last_error});
      it = job->dirty_tasks.erase(it);
    }
  }
  return batch;
}

uint64_t Scheduler::ReleaseFinishedTasks(Job& job) {
  for (uint64_t id = 0; id < job.num_tasks(); ++id)
    if (job.runtime(id).merging) return 0;  // a result being checked reads its task (Complete); next flush
  job.ReleaseTasks();
  load_.tasks -= std::exchange(job.charged_tasks, 0);
  load_.pixels -= std::exchange(job.charged_pixels, 0);
  sources_.erase(&job);
  for (auto it = held_.lower_bound({job.id(), 0}); it != held_.end() && it->first.first == job.id();)
    it = held_.erase(it);
  return job.num_tasks();
}

void Scheduler::RowsNotStored(const RowBatch& rows, const std::string& reason) {
  std::lock_guard lock(mu_);
  const std::string why = "rows not stored: " + reason;
  for (const JobRow& row : rows.jobs)
    if (Job* job = jobs_.Find(row.job_id)) {
      job->row_dirty = true;
      job->rows_storage_error = why;
    }
  for (const TaskRow& row : rows.tasks)
    if (Job* job = jobs_.Find(row.job_id)) {
      if (!job->tasks_released()) job->dirty_tasks.insert(row.task_id);
      job->rows_storage_error = why;
    }
}

void Scheduler::RowsStored(const RowBatch& rows) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    for (const JobRow& row : rows.jobs) {
      Job* job = jobs_.Find(row.job_id);
      if (!job) continue;
      job->rows_storage_error.clear();
      // A restart is stored once its row (epoch, convicted workers) is, and its empty checkpoint.
      if (job->restart_row_pending && row.epoch == job->epoch()) {
        job->restart_row_pending = false;
        if (!job->restart_pending() && job->active()) job->RestartClock(clock_.Now());
        if (!job->paused_for_storage && !job->restart_pending() && queue_.Unhold(*job)) {
          spdlog::info("job {}: its restart is stored: leasing again", job->id());
          ServeWaiters(fx);
        }
      }
    }
    for (const TaskRow& row : rows.tasks)
      if (Job* job = jobs_.Find(row.job_id)) job->rows_storage_error.clear();
  }
  Run(fx);
}

bool Scheduler::HasUncheckpointedMerges() {
  std::lock_guard lock(mu_);
  for (Job* job : jobs_.InSubmissionOrder())
    if (job->accumulator_if_loaded() && job->merge_seq() > job->checkpoint_collected_seq) return true;
  return false;
}

void Scheduler::Shutdown() {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    shutdown_ = true;
    for (auto& [id, w] : waiters_) fx.callbacks.emplace_back(std::move(w.done), std::nullopt);
    waiters_.clear();
  }
  Run(fx);
}

// ---------------------------------------------------------------------------------------------
// Photon maps traced once (map_tracing_hook.h)

void Scheduler::SetMapTracingHook(MapTracingHook* work) {
  std::lock_guard lock(mu_);
  map_hook_ = work;
}

void Scheduler::ReleaseMap(const std::string& job_id, uint64_t map_index) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
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
    ServeWaiters(fx);
  }
  Run(fx);
}

void Scheduler::NotifyMapPieces() {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    ServeWaiters(fx);
  }
  Run(fx);
}

SchedulerCounters Scheduler::counters() const {
  std::lock_guard lock(mu_);
  SchedulerCounters c = counters_;
  c.parked_polls = waiters_.size();
  for (const Job* job : jobs_.InSubmissionOrder()) c.tasks_in_memory += job->tasks().size();
  return c;
}

}  // namespace pf::server
