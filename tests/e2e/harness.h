#pragma once
// The e2e harness: real processes (pf-coordinator, pf-worker, pf, the fake worker) on
// ephemeral loopback ports, real SQLite files in a per-test folder, real EXR files read back.
// Every child gets PR_SET_PDEATHSIG, and a Process's destructor SIGKILLs and reaps it, so a
// failing (or crashing) test leaves nothing behind. The death signal follows the *thread* that
// forked: start processes from the test's main thread only.

#include <gtest/gtest.h>
#include <sys/types.h>

#include <chrono>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <map>
#include <memory>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "client/farm_client.h"
#include "common/image/image.h"

namespace pf::e2e {

// Built binaries and source paths (compile definitions from tests/e2e/CMakeLists.txt).
struct Binaries {
  static std::string Pf();
  static std::string Worker();
  static std::string Coordinator();
  static std::string FakeWorker();
  static std::string FaultyWorker();  // pf-worker with PF_TEST_* faults (faulty_worker.cpp)
  static std::string Scene();         // scenes/cornell-box/cornell-box.json
};

// A folder per test under $TMPDIR, removed at the end unless the test failed or PF_E2E_KEEP=1.
class TestDir {
 public:
  TestDir();
  ~TestDir();
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

class Process {
 public:
  // Starts argv[0] with the arguments; stdout and stderr append to `log` (both, or stdout to
  // `out` when given). `env` entries are added to the environment ("" value = unset).
  Process(std::string name, std::vector<std::string> argv, std::filesystem::path log,
          std::filesystem::path out = {}, std::map<std::string, std::string> env = {});
  ~Process();  // SIGKILL + reap if still running
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const { return pid_; }
  const std::string& name() const { return name_; }
  const std::filesystem::path& log() const { return log_; }
  void Signal(int sig);
  // Waits for exit; returns the exit code (128+signal if killed), nullopt on timeout.
  std::optional<int> Wait(double seconds);
  bool Running();

 private:
  std::string name_;
  std::filesystem::path log_;
  pid_t pid_ = -1;
  bool reaped_ = false;
  int status_ = 0;
};

std::string ReadFile(const std::filesystem::path& path);
std::vector<std::string> ReadLines(const std::filesystem::path& path);
// Lines matching `re` (search).
std::vector<std::string> Grep(const std::filesystem::path& path, const std::string& re);
// Polls `predicate` every 20 ms until it holds or `seconds` pass.
bool WaitUntil(const std::function<bool()>& predicate, double seconds);

// VmRSS and VmHWM (peak) of a process, in KiB (/proc/PID/status); -1 where a line is missing.
struct ProcessMemory {
  long rss_kib = -1, peak_kib = -1;
};
ProcessMemory MemoryOf(pid_t pid);

// A coordinator in `data_dir`; port 0 = ephemeral. Waits for its "listening on" line.
// `token_file`: the client (RenderService) token; worker tokens go in `extra_args`.
class CoordinatorProcess {
 public:
  CoordinatorProcess(const std::filesystem::path& data_dir, const std::filesystem::path& log_dir,
                     std::vector<std::string> extra_args = {}, int port = 0,
                     const std::string& token_file = "");
  // `pf-coordinator --config FILE` and `extra_args`, nothing else: no --listen, --data-dir or
  // --verify-fraction of the harness (the file's listen must print a port: 127.0.0.1:0).
  struct ConfigFileOnly {};
  CoordinatorProcess(ConfigFileOnly, const std::filesystem::path& config_file,
                     const std::filesystem::path& log_dir, const std::vector<std::string>& extra_args = {});
  const std::string& address() const { return address_; }
  int port() const { return port_; }
  int http_port() const { return http_port_; }  // the status page's ("http on" line); 0 without --http
  Process& process() { return *process_; }

 private:
  void Start(const std::vector<std::string>& argv, const std::filesystem::path& log_dir);
  std::unique_ptr<Process> process_;
  std::string address_;
  int port_ = 0;
  int http_port_ = 0;
};

// pf-worker against `address` with 1 thread, its own cache folder and log.
std::unique_ptr<Process> StartWorker(const std::string& address, const std::filesystem::path& dir,
                                     const std::string& id, std::vector<std::string> extra_args = {});
// StartWorker's command line run by the faulty worker (pf-worker with injected faults), with the
// PF_TEST_* variables (faulty_worker.cpp) in `env` that choose them.
std::unique_ptr<Process> StartFaultyWorker(const std::string& address, const std::filesystem::path& dir,
                                           const std::string& id, std::map<std::string, std::string> env,
                                           std::vector<std::string> extra_args = {});

struct RunResult {
  int exit_code = -1;
  std::string out, err;
};
// Runs a command to completion (killed after `timeout`), capturing stdout and stderr.
RunResult RunCommand(const std::vector<std::string>& argv, const std::filesystem::path& dir,
                     double timeout = 120, std::map<std::string, std::string> env = {});

inline std::vector<std::string> Concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

// Pixels of an EXR file / EXR bytes; bit-for-bit equality of two images.
Image ReadImage(const std::filesystem::path& path);
Image DecodeImage(const std::string& exr_bytes);
::testing::AssertionResult BitIdentical(const Image& a, const Image& b);

// The sum of all channels of all pixels (> 0: the image is not black).
inline double PixelSum(const Image& image) {
  double sum = 0;
  for (const Rgb& c : image.pixels()) sum += c.r + c.g + c.b;
  return sum;
}

// The photon-map skipping job the tests share: cornell-box at 32x32, stride 2, few photons.
struct JobArgs {
  std::string integrator = "photonmap";
  int photons = 2000;
  int k = 20;
  int stride = 2;
  int rounds = 2;
  int spp = 1;
  int res = 32;
  uint64_t seed = 7;
  std::vector<std::string> ToFlags() const;
};

// Per-task counts of the worker log lines "completed job=J task=T ... merged=true".
std::map<uint64_t, int> MergedTaskCounts(const std::vector<std::filesystem::path>& worker_logs,
                                         const std::string& job_id);

// How many merged completions of `job_id` the worker logs hold in all (see MergedTaskCounts).
inline size_t MergedTaskTotal(const std::vector<std::filesystem::path>& worker_logs,
                              const std::string& job_id) {
  size_t n = 0;
  for (const auto& [task, count] : MergedTaskCounts(worker_logs, job_id)) n += size_t(count);
  return n;
}

// How many lines each log holds now: where LeasedTasksSince starts reading them.
std::vector<size_t> LineCounts(const std::vector<std::filesystem::path>& logs);

// Tasks of `job_id` that the worker logs show leased ("leased job=J task=T") after their first
// `offsets` lines (LineCounts taken before, e.g., a coordinator restart).
std::set<uint64_t> LeasedTasksSince(const std::vector<std::filesystem::path>& worker_logs,
                                    const std::vector<size_t>& offsets, const std::string& job_id);

// Workers w1 and w2 (StartWorker) that retry their reports for 30 s, so that a result outlives
// a coordinator restart; `logs` receives their log files. With `seconds_per_task` > 0 they pause
// that long before each render task (the faulty worker, PF_TEST_PAUSE_AT=render): a test that
// kills the coordinator after some merges then still finds the job running, however fast the
// machine renders.
inline std::vector<std::unique_ptr<Process>> StartTwoPatientWorkers(const std::string& address,
                                                                    const std::filesystem::path& dir,
                                                                    std::vector<std::filesystem::path>* logs,
                                                                    double seconds_per_task = 0) {
  std::vector<std::unique_ptr<Process>> workers;
  for (const char* id : {"w1", "w2"}) {
    if (seconds_per_task > 0)
      workers.push_back(StartFaultyWorker(
          address, dir, id,
          {{"PF_TEST_PAUSE_AT", "render"}, {"PF_TEST_PAUSE_SECONDS", std::to_string(seconds_per_task)}},
          {"--report-retry", "30"}));
    else
      workers.push_back(StartWorker(address, dir, id, {"--report-retry", "30"}));
    logs->push_back(dir / (std::string(id) + ".log"));
  }
  return workers;
}

}  // namespace pf::e2e

namespace pf::e2e {

// Makes this process the reaper of orphaned descendants (PR_SET_CHILD_SUBREAPER), so that a
// process `pf` leaves behind becomes our child and is seen by LiveChildren().
void BecomeSubreaper();
// Children of this process that are still alive (zombies are reaped and not counted), with
// their command lines.
std::vector<std::string> LiveChildren();

// `pf render --local-only` of the shipped scene with `flags`, written to <dir>/local.exr.
inline RunResult RenderLocally(const TestDir& dir, const std::vector<std::string>& flags) {
  return RunCommand(Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, flags),
                           {"--local-only", "-o", (dir / "local.exr").string(), "--no-png", "-q"}),
                    dir.path());
}

// RenderLocally's image (a failure if pf failed).
Image RenderLocallyToImage(const TestDir& dir, const std::vector<std::string>& flags);

// `pf render --workers N` (a local farm) of the shipped scene with `flags` for each N renders
// `reference` bit for bit; the images are written to dir/<stem>N.exr.
void ExpectLocalFarmsBitIdentical(const TestDir& dir, const std::vector<std::string>& flags,
                                  const Image& reference, std::initializer_list<int> worker_counts,
                                  const std::string& stem);

// `pf submit` of the shipped scene with `flags` to `address`: the job id, or "" (with a failure)
// if it failed.
std::string SubmitJob(const TestDir& dir, const std::string& address, const std::vector<std::string>& flags);

// A coordinator on dir/data that a test will kill and restart on the same port, with the job `flags`
// submitted to it (job_id "" and a failure if the submission failed). Bound by a test as
// `auto [coordinator, port, address, job_id] = StartCoordinatorWithJob(...)`.
struct CoordinatorWithJob {
  std::unique_ptr<CoordinatorProcess> coordinator;
  int port = 0;
  std::string address;
  std::string job_id;
};
CoordinatorWithJob StartCoordinatorWithJob(const TestDir& dir, std::vector<std::string> coordinator_args,
                                           const std::vector<std::string>& flags);

// Whether the worker log shows a task leased and not yet completed, failed or abandoned.
inline bool MidTask(const std::filesystem::path& worker_log) {
  const auto leased = Grep(worker_log, "leased job=").size();
  const auto done = Grep(worker_log, "(completed|failed|abandoned) job=").size();
  return leased > done;
}

// The job's status once it is final, or the last one seen after `seconds` (a coordinator that is
// not reachable yet, e.g. restarting, counts as not final).
inline photonfarm::v1::JobStatus WaitForJob(FarmClient& client, const std::string& id, double seconds) {
  photonfarm::v1::JobStatus st;
  WaitUntil(
      [&] {
        try {
          st = client.GetJob(id);
        } catch (const std::exception&) {
          return false;
        }
        return IsFinalState(st.state());
      },
      seconds);
  return st;
}

}  // namespace pf::e2e
