#include "client/local_farm.h"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <fstream>
#include <regex>
#include <sstream>
#include <thread>

#include "common/core/error.h"

namespace pf {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

fs::path FindSiblingBinary(const std::string& subdir, const std::string& name) {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) return {};
  const fs::path here = self.parent_path();
  for (const fs::path& p : {here.parent_path() / subdir / name, here / name})
    if (fs::exists(p, ec) && access(p.c_str(), X_OK) == 0) return p;
  return {};
}

namespace {

std::string RandomToken() {
  std::ifstream in("/dev/urandom", std::ios::binary);
  unsigned char bytes[24];
  if (!in.read(reinterpret_cast<char*>(bytes), sizeof(bytes))) throw SystemError("cannot read /dev/urandom");
  static const char* hex = "0123456789abcdef";
  std::string s;
  for (unsigned char b : bytes) {
    s += hex[b >> 4];
    s += hex[b & 15];
  }
  return s;
}

std::string TailOf(const fs::path& file, size_t lines) {
  std::ifstream in(file);
  std::deque<std::string> tail;
  std::string line;
  while (std::getline(in, line)) {
    tail.push_back(line);
    if (tail.size() > lines) tail.pop_front();
  }
  std::string out;
  for (const std::string& l : tail) out += "  " + l + "\n";
  return out;
}

std::string DescribeStatus(int status) {
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return std::string("was killed by signal ") + strsignal(WTERMSIG(status));
  return "stopped";
}

}  // namespace

LocalFarm::LocalFarm(LocalFarmOptions options) : options_(std::move(options)) {
  if (options_.coordinator_bin.empty())
    options_.coordinator_bin = FindSiblingBinary("server", "pf-coordinator");
  if (options_.worker_bin.empty()) options_.worker_bin = FindSiblingBinary("worker", "pf-worker");
  if (options_.coordinator_bin.empty())
    throw SystemError(
        "cannot find pf-coordinator next to pf (build/server/ or the same folder); use --coordinator-bin");
  if (options_.worker_bin.empty())
    throw SystemError(
        "cannot find pf-worker next to pf (build/worker/ or the same folder); use --worker-bin");

  const char* tmp = std::getenv("TMPDIR");
  std::string templ = (fs::path(tmp && *tmp ? tmp : "/tmp") / "pf-farm-XXXXXX").string();
  if (!mkdtemp(templ.data()))
    throw SystemError("cannot create a temporary folder: " + std::string(strerror(errno)));
  dir_ = templ;
  // Two credentials, one per role (docs/security.md): pf uses the client token, workers theirs.
  token_ = RandomToken();
  const std::string worker_token = RandomToken();
  const fs::path token_file = dir_ / "client-token";
  const fs::path worker_token_file = dir_ / "worker-token";
  for (const auto& [file, token] :
       {std::pair{token_file, token_}, std::pair{worker_token_file, worker_token}}) {
    const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0 || ::write(fd, token.data(), token.size()) != ssize_t(token.size()) || ::close(fd) != 0)
      throw SystemError("cannot write " + file.string());
  }

  try {
    std::vector<std::string> cargs = {
        "--listen", "127.0.0.1:0", "--data-dir", (dir_ / "data").string(), "--client-token-file",
        token_file.string(), "--worker-token-file", worker_token_file.string(), "--log-level",
        options_.log_level,
        // The workers wait for a distributed map while the
        // coordinator balances it, so on one machine it may use their cores.
        "--map-build-threads", std::to_string(std::max(1, options_.workers * options_.threads_per_worker)),
        // Its workers are this machine's processes of this build: nothing to verify (docs/farm.md,
        // "Result verification").
        "--verify-fraction", "0", "--no-verify-outliers", "--verify-piece-fraction", "0"};
    cargs.insert(cargs.end(), options_.coordinator_args.begin(), options_.coordinator_args.end());
    const fs::path out = dir_ / "coordinator.out";
    Spawn("pf-coordinator", options_.coordinator_bin, cargs, out, dir_ / "coordinator.log");

    // Wait for "listening on HOST:PORT" on its stdout.
    const std::regex listening(R"(listening on ([0-9.]+:[0-9]+))");
    const Clock::time_point give_up =
        Clock::now() + std::chrono::milliseconds(int(options_.start_timeout_seconds * 1000));
    while (address_.empty()) {
      std::ifstream in(out);
      std::string line;
      std::smatch m;
      while (std::getline(in, line))
        if (std::regex_search(line, m, listening)) address_ = m[1];
      if (!address_.empty()) break;
      const std::string dead = CheckChildren();
      if (!dead.empty())
        throw SystemError(dead + "; its log (" + (dir_ / "coordinator.log").string() + "):\n" +
                          CoordinatorLogTail());
      if (Clock::now() > give_up)
        throw SystemError("pf-coordinator did not report its address within " +
                          std::to_string(int(options_.start_timeout_seconds)) + " s; its log:\n" +
                          CoordinatorLogTail());
      // A short poll: the coordinator is up in ~50-100 ms, and every worker start waits for it
      // (a 20 ms poll cost 10 ms on average of every `pf render --workers`).
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    spdlog::debug("coordinator listening on {} (pid {}), folder {}", address_, children_[0].pid,
                  dir_.string());

    for (int i = 0; i < options_.workers; ++i) {
      const std::string id = "local-" + std::to_string(i + 1);
      std::vector<std::string> wargs = {"--coordinator", address_,
                                        "--token-file",  worker_token_file.string(),
                                        "--threads",     std::to_string(options_.threads_per_worker),
                                        "--worker-id",   id,
                                        "--cache-dir",   (dir_ / ("cache-" + id)).string(),
                                        "--log-level",   options_.log_level};
      wargs.insert(wargs.end(), options_.worker_args.begin(), options_.worker_args.end());
      const fs::path log = dir_ / ("worker-" + std::to_string(i + 1) + ".log");
      Spawn("pf-worker #" + std::to_string(i + 1), options_.worker_bin, wargs, log, log);
    }
  } catch (...) {
    Shutdown(2, /*keep_logs=*/true);
    throw;
  }
}

LocalFarm::~LocalFarm() {
  Shutdown();
}

pid_t LocalFarm::Spawn(const std::string& name, const fs::path& bin, const std::vector<std::string>& args,
                       const fs::path& stdout_file, const fs::path& stderr_file) {
  // Everything the child needs is prepared before fork: after it, only async-signal-safe calls.
  std::vector<std::string> argv_storage;
  argv_storage.push_back(bin.string());
  argv_storage.insert(argv_storage.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : argv_storage) argv.push_back(a.data());
  argv.push_back(nullptr);
  const int out_fd = ::open(stdout_file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  const int err_fd = stderr_file == stdout_file
                         ? out_fd
                         : ::open(stderr_file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (out_fd < 0 || err_fd < 0) throw SystemError("cannot create log files in " + dir_.string());
  const pid_t parent = getpid();
  const pid_t group = pgid_;
  sigset_t empty;
  sigemptyset(&empty);

  const pid_t pid = fork();
  if (pid < 0) throw SystemError("fork failed: " + std::string(strerror(errno)));
  if (pid == 0) {
    // Child.
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);  // pf died before prctl took effect
    setpgid(0, group);                    // group 0 = a new group led by this child (the coordinator)
    signal(SIGPIPE, SIG_DFL);
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
    sigprocmask(SIG_SETMASK, &empty, nullptr);  // pf blocks SIGINT/SIGTERM for its signal thread
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) dup2(devnull, 0);
    dup2(out_fd, 1);
    dup2(err_fd, 2);
    execv(argv[0], argv.data());
    const char msg[] = "pf: exec failed\n";
    (void)!::write(2, msg, sizeof(msg) - 1);
    _exit(127);
  }
  setpgid(pid, group == 0 ? pid : group);  // also in the parent: no race with the first kill
  if (pgid_ == 0) pgid_ = pid;
  ::close(out_fd);
  if (err_fd != out_fd) ::close(err_fd);
  std::lock_guard lock(mutex_);
  children_.push_back(Child{name, pid});
  return pid;
}

std::string LocalFarm::CheckChildren() {
  std::lock_guard lock(mutex_);
  std::string dead;
  for (Child& c : children_) {
    if (c.reaped) continue;
    int status = 0;
    if (waitpid(c.pid, &status, WNOHANG) == c.pid) {
      c.reaped = true;
      c.status = status;
      dead += (dead.empty() ? "" : "; ") + c.name + " " + DescribeStatus(status);
    }
  }
  return dead;
}

bool LocalFarm::coordinator_alive() const {
  std::lock_guard lock(mutex_);
  return !children_.empty() && !children_[0].reaped;
}

int LocalFarm::live_workers() const {
  std::lock_guard lock(mutex_);
  int n = 0;
  for (size_t i = 1; i < children_.size(); ++i) n += !children_[i].reaped;
  return n;
}

void LocalFarm::Signal(bool workers, bool coordinator, int sig) {
  std::lock_guard lock(mutex_);
  for (size_t i = 0; i < children_.size(); ++i) {
    Child& c = children_[i];
    if (c.reaped || (i == 0 && !coordinator) || (i > 0 && !workers)) continue;
    kill(c.pid, sig);
  }
}

bool LocalFarm::WaitAll(bool workers, bool coordinator, double seconds) {
  const Clock::time_point give_up = Clock::now() + std::chrono::milliseconds(int(seconds * 1000));
  while (true) {
    bool all = true;
    std::unique_lock lock(mutex_);
    for (size_t i = 0; i < children_.size(); ++i) {
      Child& c = children_[i];
      if (c.reaped || (i == 0 && !coordinator) || (i > 0 && !workers)) continue;
      int status = 0;
      const pid_t r = waitpid(c.pid, &status, WNOHANG);
      if (r == c.pid || (r < 0 && errno == ECHILD)) {
        c.reaped = true;
        c.status = status;
      } else {
        all = false;
      }
    }
    lock.unlock();
    if (all) return true;
    if (Clock::now() >= give_up) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
}

void LocalFarm::KillNow() {
  Signal(true, true, SIGKILL);
}

void LocalFarm::Shutdown(double grace_seconds, bool keep_logs) {
  if (shut_down_) return;
  shut_down_ = true;
  // Workers first (they hand back leases), then the coordinator, then force.
  Signal(true, false, SIGTERM);
  if (!WaitAll(true, false, grace_seconds)) {
    spdlog::warn("workers did not stop within {:.0f} s: killing them", grace_seconds);
    Signal(true, false, SIGKILL);
    WaitAll(true, false, 5);
  }
  Signal(false, true, SIGTERM);
  if (!WaitAll(false, true, grace_seconds)) {
    spdlog::warn("pf-coordinator did not stop within {:.0f} s: killing it", grace_seconds);
    Signal(false, true, SIGKILL);
    WaitAll(false, true, 5);
  }
  std::lock_guard lock(mutex_);
  for (Child& c : children_)
    if (!c.reaped) {
      waitpid(c.pid, &c.status, 0);
      c.reaped = true;
    }
  if (dir_.empty()) return;
  if (options_.keep_dir || keep_logs) {
    spdlog::info("farm folder kept: {} (coordinator.log, worker-*.log, data/)", dir_.string());
  } else {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
}

std::string LocalFarm::CoordinatorLogTail(size_t lines) const {
  return TailOf(dir_ / "coordinator.log", lines);
}

}  // namespace pf
