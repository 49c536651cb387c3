#pragma once
// A real pf-coordinator process for the benchmarks that drive one over gRPC (farm_sim_bench,
// coordinator_memory_bench): started on 127.0.0.1 (an ephemeral port), its address read from its
// "listening on" line, SIGTERM and reaped on destruction; and what /proc says about it.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace pf::bench {

inline std::string ReadAll(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

class CoordinatorProcess {
 public:
  // `bin` with --data-dir `data` and --log-level warn; stdout to `out`, stderr to `log`. Throws if
  // it cannot be started or has not said where it listens after `start_seconds`.
  CoordinatorProcess(const std::string& bin, const std::filesystem::path& data,
                     const std::filesystem::path& out, const std::filesystem::path& log,
                     double start_seconds) {
    std::vector<std::string> args = {bin,           "--listen",    "127.0.0.1:0", "--data-dir",
                                     data.string(), "--log-level", "warn"};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int rc = posix_spawn(&pid_, bin.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) throw std::runtime_error("cannot start " + bin);
    const std::regex listening(R"(listening on ([0-9.]+:[0-9]+))");
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(start_seconds);
    for (;;) {
      std::smatch m;
      const std::string text = ReadAll(out);
      if (std::regex_search(text, m, listening)) {
        address_ = m[1];
        return;
      }
      if (std::chrono::steady_clock::now() >= until) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    throw std::runtime_error("pf-coordinator did not start: " + ReadAll(log));
  }
  ~CoordinatorProcess() {
    kill(pid_, SIGTERM);
    int status = 0;
    waitpid(pid_, &status, 0);
  }
  CoordinatorProcess(const CoordinatorProcess&) = delete;
  CoordinatorProcess& operator=(const CoordinatorProcess&) = delete;

  const std::string& address() const { return address_; }

  // A field of /proc/PID/status in MiB ("VmRSS", "VmHWM"); -1 if it is missing.
  double MiB(const std::string& field) const {
    std::istringstream in(ReadAll("/proc/" + std::to_string(pid_) + "/status"));
    for (std::string line; std::getline(in, line);)
      if (line.rfind(field + ":", 0) == 0) return std::stod(line.substr(field.size() + 1)) / 1024;
    return -1;
  }

  // utime + stime of the process so far (/proc/<pid>/stat fields 14 and 15).
  double CpuSeconds() const {
    const std::string stat = ReadAll("/proc/" + std::to_string(pid_) + "/stat");
    std::istringstream in(stat.substr(stat.rfind(')') + 2));
    std::string field;
    unsigned long long utime = 0, stime = 0;
    for (int i = 3; i <= 15 && in >> field; ++i) {
      if (i == 14) utime = std::stoull(field);
      if (i == 15) stime = std::stoull(field);
    }
    return double(utime + stime) / double(sysconf(_SC_CLK_TCK));
  }

 private:
  pid_t pid_ = -1;
  std::string address_;
};

}  // namespace pf::bench
