#pragma once
// LocalFarm: what `pf render SCENE --workers N` runs — one pf-coordinator on 127.0.0.1:0 with a
// temporary data directory and N pf-worker processes, all children of this process, and the
// guarantee that none of them outlives it:
//  - children run in a process group of their own (a terminal's Ctrl-C reaches only `pf`, which
//    then shuts them down in order: workers first, so they hand back their leases, then the
//    coordinator);
//  - each child asks the kernel for SIGKILL when `pf` dies (PR_SET_PDEATHSIG), so even a
//    SIGKILLed `pf` leaves nothing behind;
//  - Shutdown() sends SIGTERM, waits, then SIGKILLs stragglers and reaps every child (waitpid);
//    the destructor calls it.
// A random bearer token (0600 file in the temporary folder) guards the coordinator.
// Children are forked before any gRPC channel exists in this process, and between fork and
// exec they only make async-signal-safe calls.

#include <signal.h>
#include <sys/types.h>

#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace pf {

struct LocalFarmOptions {
  int workers = 1;
  int threads_per_worker = 1;
  std::filesystem::path coordinator_bin;  // empty: next to this executable (see FindSiblingBinary)
  std::filesystem::path worker_bin;
  std::vector<std::string> coordinator_args;  // extra flags, passed through
  std::vector<std::string> worker_args;
  std::string log_level = "info";
  bool keep_dir = false;  // keep the temporary folder (logs, SQLite) afterwards
  double start_timeout_seconds = 30;
};

class LocalFarm {
 public:
  // Starts the coordinator, waits for its "listening on HOST:PORT" line, then starts the
  // workers. Throws SystemError (with the coordinator's log tail) if anything fails to start.
  explicit LocalFarm(LocalFarmOptions options);
  ~LocalFarm();
  LocalFarm(const LocalFarm&) = delete;
  LocalFarm& operator=(const LocalFarm&) = delete;

  const std::string& address() const { return address_; }
  const std::string& token() const { return token_; }
  const std::filesystem::path& dir() const { return dir_; }

  // Orderly stop (idempotent): SIGTERM the workers, wait up to `grace` seconds, SIGTERM the
  // coordinator, wait, SIGKILL whatever is left, reap everything. Removes the temporary folder
  // unless keep_dir or `keep_logs` (used on failure, so the logs can be read).
  void Shutdown(double grace_seconds = 10, bool keep_logs = false);
  // Thread-safe (the signal thread calls these while the main thread waits): SIGTERM / SIGKILL
  // every live child at once.
  void TerminateAll() { Signal(true, true, SIGTERM); }
  void KillNow();
  // Reaps children that exited; describes them ("pf-worker #2 exited with status 1"), "" if none.
  std::string CheckChildren();
  bool coordinator_alive() const;
  int live_workers() const;
  // The last lines of the coordinator's log, for error messages.
  std::string CoordinatorLogTail(size_t lines = 20) const;

 private:
  struct Child {
    std::string name;
    pid_t pid = -1;
    bool reaped = false;
    int status = 0;
  };
  pid_t Spawn(const std::string& name, const std::filesystem::path& bin, const std::vector<std::string>& args,
              const std::filesystem::path& stdout_file, const std::filesystem::path& stderr_file);
  void Signal(bool workers, bool coordinator, int sig);
  bool WaitAll(bool workers, bool coordinator, double seconds);

  LocalFarmOptions options_;
  std::filesystem::path dir_;
  std::string address_, token_;
  mutable std::mutex mutex_;     // children_ (KillNow runs on the signal thread)
  std::vector<Child> children_;  // [0] = coordinator
  pid_t pgid_ = 0;
  bool shut_down_ = false;
};

// <dir of /proc/self/exe>/../<subdir>/<name> (the build tree: build/client/pf →
// build/server/pf-coordinator), else <dir of /proc/self/exe>/<name> (installed side by side),
// else "" .
std::filesystem::path FindSiblingBinary(const std::string& subdir, const std::string& name);

}  // namespace pf
