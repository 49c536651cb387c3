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
// The model here: tasks of a job cost about their *work* once a worker is warm (one unit per task,
// except the hierarchical plan's, whose tasks differ by orders of magnitude: Job::task_work), so
// the rate is the work completed in a recent window over the time it took, Σ_{i>1} w_i /
// (t_n − t_1); the work since the last completion is credited at that rate (at most the running
// tasks' work); and when the next completion is overdue the rate is lowered to what "a completion
// (of the mean work) right now" would give, so a stalled farm shows a growing ETA rather than a
// stuck one.
//
// Fewer than two completions (also after a coordinator restart, which keeps no completion times):
// while more work remains than is running, a warm rate will soon be measured and the average
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

  // A merge at `now` of a task of this much work.
  void RecordCompletion(double now, double work = 1) {
    completions_.push_back({now, work});
    if (completions_.size() > kWindow) completions_.pop_front();
  }

  // Seconds to go; -1 if unknown.
  //   remaining_work   work still to merge (not counting in-progress fractions)
  //   running_work     work leased right now (bounds the credit for work since the last completion)
  //   fallback         the average-rate estimate (see above for when it is used)
  double Eta(double now, double remaining_work, double running_work, double fallback) const {
    if (remaining_work <= 0) return 0;
    if (completions_.size() < 2) return remaining_work > running_work ? -1 : fallback;
    const double first = completions_.front().time;
    const double last = completions_.back().time;
    if (last <= first) return fallback;
    double after_first = 0;  // the work done in (first, last]
    for (size_t i = 1; i < completions_.size(); ++i) after_first += completions_[i].work;
    const double mean = (after_first + completions_.front().work) / double(completions_.size());
    double rate = after_first / (last - first);
    // Overdue: if the next completion (of the mean work) happened now, the rate would be
    // (work after the first + mean) / (now − first). Never more optimistic than that.
    rate = std::min(rate, (after_first + mean) / std::max(now - first, 1e-9));
    if (!(rate > 0)) return fallback;
    const double credit = std::clamp((now - last) * rate, 0.0, std::min(running_work, remaining_work));
    return (remaining_work - credit) / rate;
  }

  size_t completions() const { return completions_.size(); }

 private:
  struct Completion {
    double time;  // Clock::Now()
    double work;
  };
  std::deque<Completion> completions_;  // the latest merges, oldest first
};

}  // namespace pf::server
