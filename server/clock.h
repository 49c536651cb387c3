#pragma once
// Time, injected (docs/design.md, S5: time is injected, so timeouts are testable). The scheduler,
// the persister and the job bookkeeping read time only through a Clock: production uses
// SystemClock, tests a FakeClock they advance by hand, so lease expiry, long-poll deadlines,
// time budgets and checkpoint intervals are tested without sleeping.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>

namespace pf::server {

class Clock {
 public:
  virtual ~Clock() = default;
  // Monotonic seconds (arbitrary origin): leases, deadlines, elapsed times, rate limits.
  virtual double Now() const = 0;
  // Wall-clock milliseconds since the Unix epoch: display and persistence only.
  virtual int64_t UnixMillis() const = 0;
};

class SystemClock final : public Clock {
 public:
  double Now() const override {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
  int64_t UnixMillis() const override {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
  }
};

// Starts at 1000 s / 1.7e12 ms and moves only when told to. Thread-safe.
class FakeClock final : public Clock {
 public:
  double Now() const override {
    std::lock_guard lock(mu_);
    return now_;
  }
  int64_t UnixMillis() const override {
    std::lock_guard lock(mu_);
    return unix_base_ms_ + int64_t((now_ - 1000.0) * 1000.0);
  }
  void Advance(double seconds) {
    std::lock_guard lock(mu_);
    now_ += seconds;
  }

 private:
  mutable std::mutex mu_;
  double now_ = 1000.0;
  int64_t unix_base_ms_ = 1700000000000;
};

}  // namespace pf::server
