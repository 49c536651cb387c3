// Scheduler, part: jobs — admission of a validated job, status, cancel, snapshots, finishing
// (scheduler.h, "Jobs").
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/errors.h"
#include "server/scheduling/scheduler.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

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
      // Workers convicted of a wrong result among the results it starts from (a requeue's carried
      // checkpoint) get none of its tasks, from the first lease on.
      for (const std::string& w : j.convicted_workers)
        health_.Blocklist(j.id(), w, "convicted of a wrong result of the results it carries", clock_.Now());
      Charge(j, +1);
      if (j.paused) queue_.Hold(j);  // recovery: paused before the restart (docs/farm.md "Pausing a job")
      const std::string dependency_failed = WaitForDependencies(j);
      if (!j.waiting_for.empty()) queue_.Hold(j);
      for (uint64_t id = 0; id < j.num_tasks(); ++id)
        if (j.runtime(id).state == TaskState::kQueued) Enqueue(j, id, fx);
      AddTasksFromSource(j, fx);  // recovery: the tasks the merged results had created
      const double now = clock_.Now();
      if (!dependency_failed.empty())
        FinishJob(j, JobState::kFailed, dependency_failed, now, fx);
      else
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
  for (size_t f = 0; f < job.frame_total().size(); ++f) {
    v1::FrameProgress* fp = s.add_frames();
    fp->set_frame(job.config().first_frame + uint32_t(f));
    fp->set_tasks_done(job.frame_done()[f]);
    // What will be merged: a task a stop rule cancelled is not waited for (as tasks_total).
    fp->set_tasks_total(job.frame_total()[f] - job.frame_cancelled()[f]);
  }
  const double elapsed = job.ElapsedSeconds(now);
  s.set_elapsed_seconds(elapsed);
  s.set_rounds_done(job.rounds_done());
  s.set_submitted_unix_ms(job.submitted_unix_ms());
  s.set_samples_merged(job.samples_merged);
  if (!job.accumulator_if_loaded()) job.noise_cache = job.stored_noise_rms;
  // The estimate as last refreshed (RefreshNoise, outside this lock: it is an O(pixels) pass).
  s.set_estimated_noise_rms(job.noise_cache);
  if (!job.accumulator_if_loaded()) {
    job.estimates_cache = job.stored_estimates;  // released with the accumulator, not stored on disk
    job.estimates_cache.noise = job.noise_cache;
  }
  s.set_estimated_bias_rms(job.estimates_cache.bias);
  s.set_estimated_error_rms(job.estimates_cache.error);
  s.set_target_missed(job.target_missed);
  for (const std::string& id : job.waiting_for) s.add_waiting_for(id);
  s.set_storage_error(job.results_storage_error.empty() ? job.rows_storage_error
                      : job.rows_storage_error.empty()
                          ? job.results_storage_error
                          : job.results_storage_error + "; " + job.rows_storage_error);
  s.set_paused_for_storage(job.paused_for_storage);
  s.set_paused(job.paused && job.active());
  s.set_finished_unix_ms(job.active() ? 0 : job.finished_unix_ms);
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

std::string Scheduler::ResolveJobId(const std::string& id_or_prefix) {
  std::lock_guard lock(mu_);
  const std::string& id = jobs_.Resolve(id_or_prefix);
  // One being deleted is gone for every new reference to it (scheduler_deletion.cpp).
  if (jobs_.Get(id).deleting) throw NotFoundError("job_id: unknown job " + limits::Quote(id_or_prefix));
  return id;
}

std::shared_ptr<Job> Scheduler::FindJob(const std::string& job_id) {
  std::lock_guard lock(mu_);
  // An id or a unique prefix of one (JobRegistry::Resolve). Shared: a job deleted meanwhile
  // (RemoveJob) stays valid for this caller.
  return jobs_.Shared(jobs_.Resolve(job_id));
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
  const ErrorEstimates estimates = acc->Estimates();
  std::lock_guard lock(mu_);
  job.SetNoise(estimates, clock_.Now());
}

v1::JobStatus Scheduler::Status(const std::string& job_id) {
  const std::shared_ptr<Job> held = FindJob(job_id);
  Job& job = *held;
  RefreshNoise(job);
  std::lock_guard lock(mu_);
  return BuildStatus(job, clock_.Now());
}

void Scheduler::RefreshNoiseOfAll(bool include_finished) {
  std::vector<std::shared_ptr<Job>> jobs;
  {
    std::lock_guard lock(mu_);
    for (Job* job : jobs_.InSubmissionOrder())
      if ((include_finished || job->active()) && job->accumulator_if_loaded())
        jobs.push_back(jobs_.Shared(job->id()));
  }
  for (const std::shared_ptr<Job>& job : jobs) RefreshNoise(*job);
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
  const std::shared_ptr<Job> held = FindJob(job_id);
  Job& job = *held;
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

v1::JobStatus Scheduler::SetPaused(const std::string& job_id, bool paused) {
  Effects fx;
  const std::shared_ptr<Job> held = FindJob(job_id);
  Job& job = *held;
  {
    std::lock_guard lock(mu_);
    if (!job.active())
      throw PreconditionError("job_id: job " + limits::Quote(job.id()) + " is " + JobStateName(job.state()) +
                              ": only a queued or running job can be " + (paused ? "paused" : "resumed"));
    if (job.paused != paused) {
      job.paused = paused;
      if (paused) {
        queue_.Hold(job);  // leases in flight finish and are merged; nothing new is leased
        spdlog::info("job {}: paused: no new leases until it is resumed ({} tasks still running)", job.id(),
                     job.count(TaskState::kLeased));
      } else {
        spdlog::info("job {}: resumed", job.id());
        if (!job.held() && queue_.Unhold(job)) ServeWaiters(fx);
      }
      fx.changed.insert(job.id());
    }
  }
  Run(fx);
  std::lock_guard lock(mu_);
  return BuildStatus(job, clock_.Now());
}

JobSnapshot Scheduler::Snapshot(const std::string& job_id, bool with_image) {
  const std::shared_ptr<Job> held = FindJob(job_id);
  Job& job = *held;
  JobSnapshot snap;
  snap.config = job.shared_config();
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
    job.SetNoise(snap.image->estimates, now);  // the status says what the image says
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
  queue_.Unhold(job);       // nothing of it is queued any more: forget that it was held
  job.waiting_for.clear();  // an ended job waits for nothing
  if (state == JobState::kSucceeded && job.state() == JobState::kQueued)
    job.TransitionTo(JobState::kRunning, now);
  job.TransitionTo(state, now, reason);
  job.finished_unix_ms = clock_.UnixMillis();
  health_.JobEnded(job.id());
  verification_.DropJob(job, /*ended=*/true);
  ReleaseDependents(job, now, fx);
  // The final noise estimate is an O(pixels) pass: computed off this lock by the next status,
  // snapshot or persist (RefreshNoise, CollectPersistBatch), whichever comes first.
  Touch(job, fx);
}

void Scheduler::Charge(Job& job, int sign) {
  if (sign > 0) {
    job.charged_tasks = job.num_tasks();
    job.charged_pixels = uint64_t(job.config().camera.width) * uint64_t(job.config().image_height());
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
  const StopTargets targets = job.config().stop.targets();
  if (targets.any() && !StopTargetsMet(targets, job.estimates_cache)) {
    job.target_missed = DescribeTargets(targets, job.estimates_cache);
    spdlog::warn(
        "job {}: target not met: {}; it succeeds with the image it has ({}); `pf requeue {}` "
        "with more passes or a new budget continues it (docs/farm.md \"Requeueing a job\")",
        job.id(), job.target_missed, job.stopping ? "time budget" : "every task is done", job.id());
    activity_.TaskEvent(job.id(), "target_missed", 0, 0, "", job.target_missed);
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

}  // namespace pf::server
