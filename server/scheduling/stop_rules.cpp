#include "server/scheduling/stop_rules.h"

namespace pf::server {

bool TimeBudgetReached(const Job& job, double now) {
  const double budget = job.config().stop.time_budget_seconds;
  return budget > 0 && !job.stopping && job.active() && job.ElapsedSeconds(now) >= budget;
}

bool NoiseTargetDue(const Job& job, double now, double check_interval) {
  const StopTargets targets = job.config().stop.targets();
  // The bias fit needs kMinPassesForBias passes of every block before it says anything.
  const uint32_t coverage = targets.target_error_rms > 0 ? kMinPassesForBias : 2;
  if (!targets.any() || !job.active() || job.full_coverage() < coverage) return false;
  const bool waiting = job.count(TaskState::kQueued) + job.count(TaskState::kLeased) > 0;
  return !(now - job.noise_target_checked_at < check_interval && waiting);
}

bool NoiseTargetMet(const Job& job) {
  return StopTargetsMet(job.config().stop.targets(), job.estimates_cache);
}

}  // namespace pf::server
