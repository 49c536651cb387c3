#include "tests/e2e/harness.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "common/image/exr_io.h"

extern char** environ;

namespace pf::e2e {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// PF_E2E_BIN_DIR=DIR runs the tests against DIR/{client/pf, worker/pf-worker,
// server/pf-coordinator} of another build tree — an older commit's, to see a test fail there.
static std::string BinaryIn(const char* built, const char* relative) {
  const char* dir = std::getenv("PF_E2E_BIN_DIR");
  return dir && *dir ? std::string(dir) + "/" + relative : std::string(built);
}
std::string Binaries::Pf() {
  return BinaryIn(PF_E2E_PF, "client/pf");
}
std::string Binaries::Worker() {
  return BinaryIn(PF_E2E_WORKER, "worker/pf-worker");
}
std::string Binaries::Coordinator() {
  return BinaryIn(PF_E2E_COORDINATOR, "server/pf-coordinator");
}
std::string Binaries::FakeWorker() {
  return PF_E2E_FAKE_WORKER;
}
std::string Binaries::FaultyWorker() {
  return PF_E2E_FAULTY_WORKER;
}
std::string Binaries::Scene() {
  return std::string(PF_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.json";
}

TestDir::TestDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const char* tmp = std::getenv("TMPDIR");
  std::string name = info ? info->name() : "test";
  std::replace(name.begin(), name.end(), '/', '_');  // a parameterized test's name: "Test/param"
  std::string templ = (fs::path(tmp && *tmp ? tmp : "/tmp") / ("pf-e2e-" + name + "-XXXXXX")).string();
  if (!mkdtemp(templ.data())) throw std::runtime_error("mkdtemp failed");
  path_ = templ;
}

TestDir::~TestDir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const bool failed = info && info->result() && info->result()->Failed();
  const char* keep = std::getenv("PF_E2E_KEEP");
  if (failed || (keep && std::string(keep) == "1")) {
    std::fprintf(stderr, "e2e: kept %s\n", path_.c_str());
    return;
  }
  std::error_code ec;
  fs::remove_all(path_, ec);
}

Process::Process(std::string name, std::vector<std::string> argv, fs::path log, fs::path out,
                 std::map<std::string, std::string> env)
    : name_(std::move(name)), log_(std::move(log)) {
  std::vector<char*> args;
  for (std::string& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  // Environment prepared before fork.
  std::vector<std::string> env_storage;
  for (char** e = environ; *e; ++e) {
    const std::string kv = *e;
    const std::string key = kv.substr(0, kv.find('='));
    if (!env.count(key)) env_storage.push_back(kv);
  }
  for (const auto& [k, v] : env)
    if (!v.empty()) env_storage.push_back(k + "=" + v);
  std::vector<char*> envp;
  for (std::string& e : env_storage) envp.push_back(e.data());
  envp.push_back(nullptr);
  const int log_fd = ::open(log_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  const int out_fd =
      out.empty() ? log_fd : ::open(out.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log_fd < 0 || out_fd < 0) throw std::runtime_error("cannot open " + log_.string());
  const pid_t parent = getpid();
  pid_ = fork();
  if (pid_ < 0) throw std::runtime_error("fork failed");
  if (pid_ == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(127);
    setpgid(0, 0);  // a terminal's Ctrl-C reaches the test runner only
    sigset_t empty;
    sigemptyset(&empty);
    sigprocmask(SIG_SETMASK, &empty, nullptr);
    signal(SIGPIPE, SIG_DFL);
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) dup2(devnull, 0);
    dup2(out_fd, 1);
    dup2(log_fd, 2);
    execve(args[0], args.data(), envp.data());
    _exit(127);
  }
  ::close(log_fd);
  if (out_fd != log_fd) ::close(out_fd);
}

Process::~Process() {
  if (!reaped_ && pid_ > 0) {
    kill(pid_, SIGKILL);
    waitpid(pid_, &status_, 0);
  }
}

void Process::Signal(int sig) {
  if (!reaped_ && pid_ > 0) kill(pid_, sig);
}

bool Process::Running() {
  if (reaped_) return false;
  int status = 0;
  if (waitpid(pid_, &status, WNOHANG) == pid_) {
    reaped_ = true;
    status_ = status;
    return false;
  }
  return true;
}

std::optional<int> Process::Wait(double seconds) {
  const Clock::time_point until = Clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000));
  while (Running()) {
    if (Clock::now() >= until) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (WIFEXITED(status_)) return WEXITSTATUS(status_);
  if (WIFSIGNALED(status_)) return 128 + WTERMSIG(status_);
  return -1;
}

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<std::string> ReadLines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

std::vector<std::string> Grep(const fs::path& path, const std::string& re) {
  const std::regex r(re);
  std::vector<std::string> out;
  for (const std::string& l : ReadLines(path))
    if (std::regex_search(l, r)) out.push_back(l);
  return out;
}

bool WaitUntil(const std::function<bool()>& predicate, double seconds) {
  const Clock::time_point until = Clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000));
  while (!predicate()) {
    if (Clock::now() >= until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

CoordinatorProcess::CoordinatorProcess(const fs::path& data_dir, const fs::path& log_dir,
                                       std::vector<std::string> extra_args, int port,
                                       const std::string& token_file) {
  std::vector<std::string> argv = {Binaries::Coordinator(), "--listen", "127.0.0.1:" + std::to_string(port),
                                   "--data-dir", data_dir.string()};
  if (!token_file.empty()) argv.insert(argv.end(), {"--client-token-file", token_file});
  // No verification leases at random unless the test asks for them (docs/farm.md "Result
  // verification"): several tests count leases and merges exactly.
  if (std::find(extra_args.begin(), extra_args.end(), "--verify-fraction") == extra_args.end())
    argv.insert(argv.end(), {"--verify-fraction", "0"});
  argv.insert(argv.end(), extra_args.begin(), extra_args.end());
  Start(argv, log_dir);
}

CoordinatorProcess::CoordinatorProcess(ConfigFileOnly, const fs::path& config_file, const fs::path& log_dir,
                                       const std::vector<std::string>& extra_args) {
  Start(Concat({Binaries::Coordinator(), "--config", config_file.string()}, extra_args), log_dir);
}

void CoordinatorProcess::Start(const std::vector<std::string>& argv, const fs::path& log_dir) {
  static int counter = 0;
  const std::string n = std::to_string(++counter);
  const fs::path out = log_dir / ("coordinator-" + n + ".out");
  process_ = std::make_unique<Process>(
      "pf-coordinator", argv, log_dir / ("coordinator-" + n + ".log"), out,
      std::map<std::string, std::string>{{"PF_TOKEN", ""}, {"PF_CLIENT_TOKEN", ""}, {"PF_WORKER_TOKEN", ""}});
  const std::regex listening(R"(listening on ([0-9.]+):([0-9]+))");
  const std::regex http(R"(http on \S+:([0-9]+))");  // printed with the line above
  const bool ok = WaitUntil(
      [&] {
        std::smatch m;
        const std::string text = ReadFile(out);
        if (!std::regex_search(text, m, listening)) return false;
        address_ = m[1].str() + ":" + m[2].str();
        port_ = std::stoi(m[2].str());
        if (std::regex_search(text, m, http)) http_port_ = std::stoi(m[1].str());
        return true;
      },
      30);
  if (!ok) throw std::runtime_error("pf-coordinator did not start: " + ReadFile(process_->log()));
}

namespace {
// A worker's command line: `binary` against `address` with 1 thread, its own cache folder.
std::vector<std::string> WorkerArgv(const std::string& binary, const std::string& address,
                                    const fs::path& dir, const std::string& id,
                                    const std::vector<std::string>& extra_args) {
  std::vector<std::string> argv = {binary,
                                   "--coordinator",
                                   address,
                                   "--threads",
                                   "1",
                                   "--worker-id",
                                   id,
                                   "--cache-dir",
                                   (dir / ("cache-" + id)).string(),
                                   "--poll-seconds",
                                   "1",
                                   "--max-backoff",
                                   "0.5"};
  argv.insert(argv.end(), extra_args.begin(), extra_args.end());
  return argv;
}
}  // namespace

std::unique_ptr<Process> StartWorker(const std::string& address, const fs::path& dir, const std::string& id,
                                     std::vector<std::string> extra_args) {
  return std::make_unique<Process>(id, WorkerArgv(Binaries::Worker(), address, dir, id, extra_args),
                                   dir / (id + ".log"));
}

std::unique_ptr<Process> StartFaultyWorker(const std::string& address, const fs::path& dir,
                                           const std::string& id, std::map<std::string, std::string> env,
                                           std::vector<std::string> extra_args) {
  return std::make_unique<Process>(id, WorkerArgv(Binaries::FaultyWorker(), address, dir, id, extra_args),
                                   dir / (id + ".log"), fs::path{}, std::move(env));
}

RunResult RunCommand(const std::vector<std::string>& argv, const fs::path& dir, double timeout,
                     std::map<std::string, std::string> env) {
  static int counter = 0;
  const std::string n = std::to_string(++counter);
  const fs::path out = dir / ("run-" + n + ".out"), err = dir / ("run-" + n + ".err");
  Process p("run", argv, err, out, std::move(env));
  RunResult r;
  const std::optional<int> code = p.Wait(timeout);
  r.exit_code = code.value_or(-1);
  r.out = ReadFile(out);
  r.err = ReadFile(err);
  return r;
}

Image RenderLocallyToImage(const TestDir& dir, const std::vector<std::string>& flags) {
  const RunResult r = RenderLocally(dir, flags);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return ReadImage(dir / "local.exr");
}

void ExpectLocalFarmsBitIdentical(const TestDir& dir, const std::vector<std::string>& flags,
                                  const Image& reference, std::initializer_list<int> worker_counts,
                                  const std::string& stem) {
  for (int workers : worker_counts) {
    const std::string out = (dir / (stem + std::to_string(workers) + ".exr")).string();
    const RunResult r = RunCommand(
        Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, flags),
               {"--workers", std::to_string(workers), "--threads", "1", "-o", out, "--no-png", "-q"}),
        dir.path());
    ASSERT_EQ(r.exit_code, 0) << "workers=" << workers << "\n" << r.err;
    EXPECT_TRUE(BitIdentical(ReadImage(out), reference)) << "workers=" << workers;
  }
}

Image ReadImage(const fs::path& path) {
  return ReadExr(path);
}
Image DecodeImage(const std::string& bytes) {
  return DecodeExrFromMemory(bytes);
}

::testing::AssertionResult BitIdentical(const Image& a, const Image& b) {
  if (a.width() != b.width() || a.height() != b.height())
    return ::testing::AssertionFailure()
           << "sizes differ: " << a.width() << "x" << a.height() << " vs " << b.width() << "x" << b.height();
  for (int y = 0; y < a.height(); ++y)
    for (int x = 0; x < a.width(); ++x) {
      const Rgb& p = a.at(x, y);
      const Rgb& q = b.at(x, y);
      if (std::memcmp(&p, &q, sizeof(Rgb)) != 0)
        return ::testing::AssertionFailure()
               << "pixel (" << x << "," << y << ") differs: (" << p.r << "," << p.g << "," << p.b << ") vs ("
               << q.r << "," << q.g << "," << q.b << ")";
    }
  return ::testing::AssertionSuccess();
}

std::vector<std::string> JobArgs::ToFlags() const {
  std::vector<std::string> flags = {"--integrator", integrator,
                                    "--plan",       "skipping",
                                    "--stride",     std::to_string(stride),
                                    "--rounds",     std::to_string(rounds),
                                    "--spp",        std::to_string(spp),
                                    "--res",        std::to_string(res) + "x" + std::to_string(res),
                                    "--seed",       std::to_string(seed)};
  // pf refuses photon-map options for the path tracer (RejectPhotonMapOptionsForPath).
  if (integrator == "photonmap")
    flags.insert(flags.end(), {"--photons", std::to_string(photons), "--k", std::to_string(k)});
  return flags;
}

std::map<uint64_t, int> MergedTaskCounts(const std::vector<fs::path>& worker_logs,
                                         const std::string& job_id) {
  const std::regex re("completed job=" + job_id + " task=([0-9]+) attempt=[0-9]+ merged=true");
  std::map<uint64_t, int> counts;
  for (const fs::path& log : worker_logs)
    for (const std::string& l : ReadLines(log)) {
      std::smatch m;
      if (std::regex_search(l, m, re)) ++counts[std::stoull(m[1].str())];
    }
  return counts;
}

ProcessMemory MemoryOf(pid_t pid) {
  ProcessMemory m;
  for (const std::string& line : ReadLines("/proc/" + std::to_string(pid) + "/status")) {
    if (line.rfind("VmRSS:", 0) == 0) m.rss_kib = std::stol(line.substr(6));
    if (line.rfind("VmHWM:", 0) == 0) m.peak_kib = std::stol(line.substr(6));
  }
  return m;
}

std::vector<size_t> LineCounts(const std::vector<fs::path>& logs) {
  std::vector<size_t> counts;
  for (const fs::path& log : logs) counts.push_back(ReadLines(log).size());
  return counts;
}

std::set<uint64_t> LeasedTasksSince(const std::vector<fs::path>& worker_logs,
                                    const std::vector<size_t>& offsets, const std::string& job_id) {
  std::set<uint64_t> leased;
  const std::regex re("leased job=" + job_id + " task=([0-9]+)");
  for (size_t i = 0; i < worker_logs.size(); ++i) {
    const std::vector<std::string> lines = ReadLines(worker_logs[i]);
    for (size_t l = offsets[i]; l < lines.size(); ++l) {
      std::smatch m;
      if (std::regex_search(lines[l], m, re)) leased.insert(std::stoull(m[1].str()));
    }
  }
  return leased;
}

}  // namespace pf::e2e

namespace pf::e2e {

std::string SubmitJob(const TestDir& dir, const std::string& address, const std::vector<std::string>& flags) {
  const RunResult r = RunCommand(
      Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, flags), {"--coordinator", address}),
      dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return "";
  std::string id = r.out;
  while (!id.empty() && (id.back() == '\n' || id.back() == ' ')) id.pop_back();
  return id;
}

CoordinatorWithJob StartCoordinatorWithJob(const TestDir& dir, std::vector<std::string> coordinator_args,
                                           const std::vector<std::string>& flags) {
  CoordinatorWithJob out;
  out.coordinator =
      std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::move(coordinator_args));
  out.port = out.coordinator->port();
  out.address = out.coordinator->address();
  out.job_id = SubmitJob(dir, out.address, flags);
  return out;
}

void BecomeSubreaper() {
  prctl(PR_SET_CHILD_SUBREAPER, 1);
}

std::vector<std::string> LiveChildren() {
  // Reap zombies first (orphans re-parented to us that already exited).
  while (waitpid(-1, nullptr, WNOHANG) > 0) {
  }
  std::vector<std::string> out;
  const pid_t self = getpid();
  for (const auto& e : fs::directory_iterator("/proc")) {
    const std::string name = e.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const std::string stat = ReadFile(e.path() / "stat");
    const size_t close = stat.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream in(stat.substr(close + 2));
    char state = 0;
    pid_t ppid = 0;
    in >> state >> ppid;
    if (ppid != self || state == 'Z') continue;
    std::string cmd = ReadFile(e.path() / "cmdline");
    std::replace(cmd.begin(), cmd.end(), '\0', ' ');
    out.push_back(name + ": " + cmd);
  }
  return out;
}

}  // namespace pf::e2e
