// Scheduler, part: job dependencies (scheduler.h; docs/farm.md "Job dependencies"). A job whose
// spec names other jobs in `after` is held — its tasks queued, none leased — until every one of
// them has SUCCEEDED, and FAILS, naming the job, when one fails or is cancelled. Only the
// dependencies' states decide, so a restarted coordinator re-derives the same answer: jobs are
// added in submission order and a dependency is always submitted before its dependents (its id
// must be known at admission), and a job named by a live job's `after` cannot be deleted
// (CheckRemovable, which also makes a job being deleted unnameable).
#include <spdlog/spdlog.h>

#include <algorithm>

#include "proto/limits.h"
#include "server/errors.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {

std::string Scheduler::WaitForDependencies(Job& job) {
  for (const std::string& id : job.config().after) {
    // A job that has started, or that succeeded before and is rendered again (recovery), had
    // every dependency succeed (a restart may not know one any more: its spec no longer loads).
    if (job.state() != JobState::kQueued || job.dependencies_met) continue;
    const Job* dependency = jobs_.Find(id);
    if (!dependency || dependency->deleting)
      return "job " + limits::Quote(id) + " it waits for (--after) is unknown to this coordinator";
    if (dependency->state() == JobState::kSucceeded) continue;
    if (!dependency->active())
      return "job " + id + " it waits for (--after) ended " + JobStateName(dependency->state());
    job.waiting_for.insert(id);
  }
  if (!job.waiting_for.empty())
    spdlog::info("job {}: waits for {} job(s) (--after), first {}", job.id(), job.waiting_for.size(),
                 *job.waiting_for.begin());
  return "";
}

void Scheduler::ReleaseDependents(const Job& job, double now, Effects& fx) {
  for (Job* dependent : jobs_.InSubmissionOrder()) {
    if (!dependent->active() || dependent->waiting_for.erase(job.id()) == 0) continue;
    fx.changed.insert(dependent->id());
    if (job.state() != JobState::kSucceeded) {
      spdlog::warn("job {}: fails: job {} it waits for (--after) ended {}", dependent->id(), job.id(),
                   JobStateName(job.state()));
      // Its own dependents fail in turn (FinishJob calls this again).
      FinishJob(*dependent, JobState::kFailed,
                "job " + job.id() + " it waits for (--after) ended " + JobStateName(job.state()), now, fx);
      continue;
    }
    if (!dependent->waiting_for.empty()) continue;
    spdlog::info("job {}: every job it waits for (--after) succeeded; it starts", dependent->id());
    if (!dependent->held() && queue_.Unhold(*dependent)) ServeWaiters(fx);
  }
}

}  // namespace pf::server
