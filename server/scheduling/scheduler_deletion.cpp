// Scheduler, part: deleting a finished job (scheduler.h, "Jobs"; docs/farm.md "Deleting jobs"), and
// the finished job a requeue starts from.
// The job leaves every structure that names it, under the one lock; holders of the Job itself
// (FindJob, Complete, CollectCheckpoints: shared) keep a valid object nothing reaches any more.
#include <spdlog/spdlog.h>

#include <utility>

#include "proto/limits.h"
#include "server/errors.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {

Job& Scheduler::RemovableLocked(const std::string& job_id) {
  Job& job = jobs_.Get(jobs_.Resolve(job_id));
  if (job.active())
    throw PreconditionError("job_id: job " + limits::Quote(job.id()) + " is " + JobStateName(job.state()) +
                            ": only a succeeded, failed or cancelled job can be deleted (cancel it first)");
  // A verification with the referee reads the Job when its verdict comes (RefereeVerdict).
  if (verification_.Names(job))
    throw PreconditionError("job_id: job " + limits::Quote(job.id()) +
                            ": a verification of its results is still with the referee; try again once it "
                            "is decided (pf events shows it)");
  return job;
}

std::string Scheduler::CheckRemovable(const std::string& job_id) {
  std::lock_guard lock(mu_);
  Job& job = RemovableLocked(job_id);
  // A live job that names it in --after would find no dependency after a restart and fail (a
  // running one too: its RUNNING row may not be stored yet). Checked here only, and the job
  // marked: from now on no new job can name it (ResolveJobId, WaitForDependencies) nor requeue
  // it, so RemoveJob, after the rows are gone, has no reason to refuse.
  for (const Job* other : jobs_.InSubmissionOrder())
    if (other->active() && std::find(other->config().after.begin(), other->config().after.end(), job.id()) !=
                               other->config().after.end())
      throw PreconditionError("job_id: job " + limits::Quote(job.id()) +
                              " is a dependency (--after) of job " + limits::Quote(other->id()) +
                              ", which is " + JobStateName(other->state()) +
                              "; it can be deleted once that job has ended");
  job.deleting = true;
  return job.id();
}

Scheduler::FinishedJob Scheduler::FinishedJobOf(const std::string& job_id) {
  std::lock_guard lock(mu_);
  const Job& job = jobs_.Get(jobs_.Resolve(job_id));
  if (job.deleting) throw NotFoundError("job_id: job " + limits::Quote(job.id()) + " is being deleted");
  if (job.active())
    throw PreconditionError("job_id: job " + limits::Quote(job.id()) + " is " + JobStateName(job.state()) +
                            ": only a succeeded, failed or cancelled job can be requeued");
  FinishedJob out;
  out.job_id = job.id();
  out.config = job.shared_config();
  out.state = job.state();
  out.tasks_total = job.num_tasks();
  out.tasks_done = job.count(TaskState::kDone);
  out.checkpoint_path = job.checkpoint_path;
  out.seal = job.checkpoint_seal;
  return out;
}

std::shared_ptr<const JobConfig> Scheduler::RemoveJob(const std::string& job_id) {
  Effects fx;
  std::shared_ptr<const JobConfig> config;
  {
    std::lock_guard lock(mu_);
    Job& job = RemovableLocked(job_id);
    const std::string id = job.id();
    config = job.shared_config();
    // FinishJob dequeued its tasks and erased its leases; what is left names the job by pointer or id.
    queue_.Forget(job);
    sources_.erase(&job);
    for (auto it = held_.lower_bound({id, 0}); it != held_.end() && it->first.first == id;)
      it = held_.erase(it);
    // Its tasks and pixels count until released (ReleaseFinishedTasks); a job deleted before that
    // gives them back here.
    load_.tasks -= std::exchange(job.charged_tasks, 0);
    load_.pixels -= std::exchange(job.charged_pixels, 0);
    health_.ForgetJob(id);
    verification_.ForgetJob(job);
    activity_.ForgetJob(id);
    const std::shared_ptr<Job> removed = jobs_.Remove(id);
    spdlog::info("job {}: deleted ({})", id, JobStateName(removed->state()));
    fx.changed.insert(id);  // its watchers end (NOT_FOUND)
  }
  Run(fx);
  return config;
}

std::vector<std::string> Scheduler::FinishedBefore(int64_t cutoff_unix_ms) const {
  std::lock_guard lock(mu_);
  std::vector<std::pair<int64_t, std::string>> ended;
  for (const Job* job : jobs_.InSubmissionOrder())
    if (!job->active() && job->finished_unix_ms > 0 && job->finished_unix_ms < cutoff_unix_ms)
      ended.emplace_back(job->finished_unix_ms, job->id());
  std::stable_sort(ended.begin(), ended.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<std::string> ids;
  for (auto& [ms, id] : ended) ids.push_back(std::move(id));
  return ids;
}

std::vector<std::shared_ptr<const JobConfig>> Scheduler::JobConfigs() const {
  std::lock_guard lock(mu_);
  std::vector<std::shared_ptr<const JobConfig>> out;
  for (const Job* job : jobs_.InSubmissionOrder()) out.push_back(job->shared_config());
  return out;
}

std::vector<Scheduler::KnownJob> Scheduler::KnownJobs() const {
  std::lock_guard lock(mu_);
  std::vector<KnownJob> out;
  for (const Job* job : jobs_.InSubmissionOrder())
    // A finished job whose results a verification still has with the referee counts as live: the
    // referee may render its tasks.
    out.push_back({job->id(), job->shared_config(), job->active() || verification_.Names(*job)});
  return out;
}

}  // namespace pf::server
