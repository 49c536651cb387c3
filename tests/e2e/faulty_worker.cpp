// pf-worker with injected faults (worker/worker_faults.h), for the kill-point, paced and
// corrupted-map tests (map_tracing_test.cpp, hierarchical_test.cpp): the same process as pf-worker
// (RunWorkerProcess), plus
//   PF_TEST_PAUSE_AT=trace|upload|fetch|render[:TEXT]  sleep at that step (only where the task's context
//                                               contains TEXT, e.g. "upload:piece=2/"), logging
//                                               "test-pause at ..." so a test can SIGKILL it there;
//   PF_TEST_PAUSE_SECONDS=S                     how long (default 120): a pause that ends stands
//                                               for a slow step;
//   PF_TEST_CORRUPT_MAP_PART=1                  flip a byte of the first map part received.
// The variables are read here, in the test binary: production code reads none.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>

#include "worker/worker_main.h"

namespace {

class EnvironmentFaults : public pf::worker::WorkerFaults {
 public:
  EnvironmentFaults() {
    if (const char* at = std::getenv("PF_TEST_PAUSE_AT")) pause_at_ = at;
    if (const char* s = std::getenv("PF_TEST_PAUSE_SECONDS"))
      pause_seconds_ = std::clamp(std::atof(s), 0.0, 120.0);
    corrupt_next_part_ = std::getenv("PF_TEST_CORRUPT_MAP_PART") != nullptr;
  }

  void At(const char* where, const std::string& context) override {
    if (pause_at_.empty()) return;
    const size_t colon = pause_at_.find(':');
    if (pause_at_.substr(0, colon) != where) return;
    if (colon != std::string::npos && context.find(pause_at_.substr(colon + 1)) == std::string::npos) return;
    spdlog::warn("test-pause at {} {} for {:.1f} s (PF_TEST_PAUSE_AT)", where, context, pause_seconds_);
    std::this_thread::sleep_for(std::chrono::duration<double>(pause_seconds_));
    spdlog::warn("test-pause over at {} {}", where, context);
  }

  void OnMapPart(std::string& data, uint32_t index, const std::string& map_key) override {
    if (!corrupt_next_part_ || data.empty()) return;
    corrupt_next_part_ = false;  // once per process
    data[data.size() / 2] = char(data[data.size() / 2] ^ 0x5a);
    spdlog::warn("PF_TEST_CORRUPT_MAP_PART: part {} of map {} corrupted on arrival", index,
                 map_key.substr(0, 12));
  }

 private:
  std::string pause_at_;
  double pause_seconds_ = 120;
  bool corrupt_next_part_ = false;
};

}  // namespace

int main(int argc, char** argv) {
  return pf::worker::RunWorkerProcess(argc, argv, std::make_shared<EnvironmentFaults>());
}
