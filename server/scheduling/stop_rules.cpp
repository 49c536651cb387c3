#include "server/scheduling/stop_rules.h"

namespace pf::server {

bool TimeBudgetReached(const Job& job, double now) {
  const double budget = job.config().stop.time_budget_seconds;
  return budget > 0 && !job.stopping && job.active() && job.ElapsedSeconds(now) >= budget;
}

bool NoiseTargetDue(const Job& job, double now, double check_interval) {
  if (job.config().stop.target_noise_rms <= 0 || !job.active() || job.full_coverage() < 2) return false;
  const bool waiting = job.count(TaskState::kQueued) + job.count(TaskState::kLeased) > 0;
  return !(now - job.noise_target_checked_at < check_interval && waiting);
}

bool NoiseTargetMet(const Job& job) {
  return job.noise_cache >= 0 && job.noise_cache <= job.config().stop.target_noise_rms;
}

}  // namespace pf::server
