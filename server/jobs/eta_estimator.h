#pragma once
// A job's ETA from its recent throughput, not from its average since the start.
//
// Why not elapsed × remaining / done: a job's first tasks carry fixed costs the later ones do not
// (each worker loads the scene and traces and balances its photon map once, then renders many
// tiles from it), and workers report a task's progress only at heartbeats (every third of the
// lease, 10 s by default), so early on the average rate under-counts the work done. Measured on
// the default job (Cornell box, 1M photons, 16 tiles, one worker): that formula was 3.0× the true
// remaining time after the first tile, 1.6× after three and still 1.2–1.4× half way.
//
// The model here: tasks of a job cost about the same once a worker is warm, so the rate is the
// number of completions in a recent window over the time they took, (n − 1) / (t_n − t_1); the
// work since the last completion is credited at that rate (at most one task per running lease);
// and when the next completion is overdue the rate is lowered to what "a completion right now"
// would give, so a stalled farm shows a growing ETA rather than a stuck one.
//
// Fewer than two completions (also after a coordinator restart, which keeps no completion times):
// while more tasks remain than are running, a warm rate will soon be measured and the average
// would be 2–3× too high (3.2× measured after the first tile), so the ETA is unknown (-1, shown
// as "?"); when every remaining task is already running (few large tasks, one per worker), no
// better rate will come, and the average-rate formula with heartbeat progress is used.

#include <algorithm>
#include <cstddef>
#include <deque>

namespace pf::server {

class EtaEstimator {
 public:
  // The completions that define "recent": enough to average over several workers' tiles, few
  // enough that the rate follows workers joining or leaving within a few dozen tasks.
  static constexpr size_t kWindow = 32;

  void RecordCompletion(double now) {
    completions_.push_back(now);
    if (completions_.size() > kWindow) completions_.pop_front();
  }

  // Seconds to go; -1 if unknown.
  //   remaining_tasks   tasks still to merge (not counting in-progress fractions)
  //   running_tasks     tasks leased right now (bounds the credit for work since the last completion)
  //   fallback          the average-rate estimate (see above for when it is used)
  double Eta(double now, double remaining_tasks, double running_tasks, double fallback) const {
    if (remaining_tasks <= 0) return 0;
    if (completions_.size() < 2) return remaining_tasks > running_tasks ? -1 : fallback;
    const double first = completions_.front();
    const double last = completions_.back();
    if (last <= first) return fallback;
    const double n = double(completions_.size());
    double rate = (n - 1) / (last - first);
    // Overdue: if the next completion happened now, the rate would be n / (now − first)
    // (n − 1 intervals and the current one). Never more optimistic than that.
    rate = std::min(rate, n / std::max(now - first, 1e-9));
    const double credit = std::clamp((now - last) * rate, 0.0, std::min(running_tasks, remaining_tasks));
    return (remaining_tasks - credit) / rate;
  }

  size_t completions() const { return completions_.size(); }

 private:
  std::deque<double> completions_;  // Clock::Now() of the latest merges, oldest first
};

}  // namespace pf::server
