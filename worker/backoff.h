#pragma once
// The worker's wait between attempts to reach the coordinator (docs/farm.md, "Worker",
// "Connecting / backoff"): exponential, 100 ms · 2ⁿ after n failures in a row, capped, with
// "equal jitter" — half fixed, half random — so that workers that lost the coordinator together
// do not reconnect in lockstep. Used by the pull loop for reconnects and CompleteTask retries.

#include <cstdint>
#include <random>

namespace pf::worker {

class Backoff {
 public:
  // `cap_seconds` > 0; `seed` draws the jitter (pf-worker: std::random_device).
  Backoff(double cap_seconds, uint64_t seed) : cap_(cap_seconds), rng_(seed) {}

  // The next wait, in [0.5, 1) · min(cap, 0.1 · 2^failures); counts one more failure.
  double NextSeconds();
  // Failures in a row so far (the exponent of the next wait).
  int failures() const { return failures_; }
  // A call went through: the next failure starts again from 100 ms.
  void Reset() { failures_ = 0; }
  // At least `failures` failures in a row: a retry loop that counts its own attempts.
  void AtLeast(int failures);
  // The slowest rate (an error only an operator can fix, e.g. a wrong token).
  void Slowest() { failures_ = 16; }

 private:
  double cap_;
  int failures_ = 0;
  std::mt19937_64 rng_;
};

}  // namespace pf::worker
