#pragma once
// Progress on stderr: a bar with percentage and ETA on a terminal, a line per 10 % otherwise
// (logs and CI). ProgressBar follows an in-process counter; FarmProgress follows the
// coordinator's JobStatus (tasks done, running, ETA, estimated noise).

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>
#include <thread>

#include "photonfarm/v1/farm.pb.h"

namespace pf {

class ProgressBar {
 public:
  ProgressBar(const std::atomic<uint64_t>& done, uint64_t total, bool enabled);
  ~ProgressBar() { Finish(); }
  void Finish();

 private:
  void Run();
  void Draw(bool final);
  const std::atomic<uint64_t>& done_;
  uint64_t total_;
  bool enabled_, tty_;
  std::atomic<bool> stop_{false};
  int last_decile_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::thread thread_;
};

class FarmProgress {
 public:
  explicit FarmProgress(bool enabled);
  ~FarmProgress() { Finish(); }
  void Update(const photonfarm::v1::JobStatus& status);
  void Finish();  // ends the bar's line

 private:
  bool enabled_, tty_;
  bool drawn_ = false;
  int last_decile_ = -1;
  photonfarm::v1::JobState last_state_ = photonfarm::v1::JOB_STATE_UNSPECIFIED;
  std::string last_storage_error_;
};

// "1.2 s", "3 min 4 s", "2 h 5 min".
std::string FormatDuration(double seconds);

}  // namespace pf
