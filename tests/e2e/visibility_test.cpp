// Farm visibility with real processes (docs/farm.md, "Command-line contract"): `pf workers`, `pf events JOB`
// (which worker ran which task, retries, failures), the hint of `pf watch` when no worker is there, the farm
// EXR's header read back by `pf info`, and a clean coordinator restart that workers take calmly.
#include <signal.h>

#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "client/farm_client.h"
#include "photonfarm_version.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;

std::string Submit(const TestDir& dir, const std::string& address, const JobArgs& job) {
  const RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()),
                                        {"--coordinator", address}),
                                 dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return r.out.substr(0, r.out.find('\n'));
}

TEST(Visibility, WorkersAndEventsShowWhoRanWhatAndTheRetries) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--max-attempts", "5"});
  const std::vector<std::string> at = {"--coordinator", coordinator.address()};
  JobArgs job;
  job.rounds = 2;  // 8 tasks
  const std::string id = Submit(dir, coordinator.address(), job);
  // A fake worker returning NaN results first: its attempts are rejected and retried.
  Process bad(
      "fake-nan",
      {Binaries::FakeWorker(), "--coordinator", coordinator.address(), "--mode", "nan", "--wait", "10"},
      dir / "fake.log");
  ASSERT_TRUE(WaitUntil([&] { return !bad.Running(); }, 30)) << ReadFile(dir / "fake.log");
  auto w1 = StartWorker(coordinator.address(), dir.path(), "w1");
  auto w2 = StartWorker(coordinator.address(), dir.path(), "w2");
  RunResult r = RunCommand(Concat({Binaries::Pf(), "watch", id, "-q"}, at), dir.path(), 120);
  ASSERT_EQ(r.exit_code, 0) << r.err;

  r = RunCommand(Concat({Binaries::Pf(), "workers", "--json"}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json workers = nlohmann::json::parse(r.out);
  std::map<std::string, nlohmann::json> by_id;
  for (const auto& w : workers) by_id[w["worker_id"]] = w;
  ASSERT_TRUE(by_id.count("w1") && by_id.count("w2")) << r.out;
  EXPECT_EQ(by_id["w1"]["tasks_done"].get<int>() + by_id["w2"]["tasks_done"].get<int>(), 8) << r.out;
  EXPECT_EQ(by_id["w1"]["threads"], 1);
  EXPECT_FALSE(by_id["w1"]["busy"].get<bool>());
  EXPECT_GT(by_id["w1"]["photons_per_second"].get<double>() + by_id["w2"]["photons_per_second"].get<double>(),
            0);
  EXPECT_NE(by_id["w1"]["peer"].get<std::string>().find("127.0.0.1"), std::string::npos) << r.out;
  // Each real worker names its build, the coordinator's own (docs/farm.md, "Upgrades").
  EXPECT_EQ(by_id["w1"]["version"], PF_VERSION) << r.out;
  EXPECT_EQ(by_id["w2"]["version"], PF_VERSION) << r.out;

  r = RunCommand(Concat({Binaries::Pf(), "events", id, "--json"}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json events = nlohmann::json::parse(r.out)["events"];
  std::map<uint64_t, std::string> merged_by;
  std::set<uint64_t> rejected;
  for (const auto& e : events) {
    if (e["kind"] == "merged") {
      EXPECT_FALSE(merged_by.count(e["task_id"])) << "merged twice: " << e;
      merged_by[e["task_id"]] = e["worker_id"];
    }
    if (e["kind"] == "rejected") {
      rejected.insert(e["task_id"].get<uint64_t>());
      EXPECT_NE(e["detail"].get<std::string>().find("finite"), std::string::npos) << e;
    }
  }
  EXPECT_EQ(merged_by.size(), 8u) << r.out;
  for (const auto& [task, worker] : merged_by) EXPECT_TRUE(worker == "w1" || worker == "w2") << worker;
  EXPECT_FALSE(rejected.empty()) << "the fake worker's NaN results appear as rejected attempts\n" << r.out;

  // The table form names the workers too; an unknown job is NOT_FOUND (exit 3).
  r = RunCommand(Concat({Binaries::Pf(), "events", id}, at), dir.path());
  EXPECT_NE(r.out.find("rejected"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("w1"), std::string::npos) << r.out;
  r = RunCommand(Concat({Binaries::Pf(), "events", "job-unknown"}, at), dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
}

// Events and worker statistics outlive the coordinator (docs/farm.md "Activity across restarts"):
// SIGKILLed two seconds after the job ended — the activity is stored every second — the next life
// lists the job's events and the worker's merged tasks as the first life did.
TEST(Visibility, EventsAndWorkerStatisticsSurviveACoordinatorKill) {
  TestDir dir;
  std::string id;
  size_t events_before = 0;
  {
    CoordinatorProcess coordinator(dir / "data", dir.path());
    id = Submit(dir, coordinator.address(), JobArgs{});
    auto w1 = StartWorker(coordinator.address(), dir.path(), "w1");
    FarmClient client(coordinator.address(), "");
    ASSERT_EQ(WaitForJob(client, id, 120).state(), photonfarm::v1::JOB_STATE_SUCCEEDED);
    events_before = size_t(client.ListJobEvents(id).events_size());
    ASSERT_GE(events_before, 16u) << "8 tasks, each leased and merged";
    w1->Signal(SIGTERM);
    ASSERT_TRUE(w1->Wait(20).has_value());
    std::this_thread::sleep_for(std::chrono::milliseconds(2500));
    coordinator.process().Signal(SIGKILL);
    ASSERT_TRUE(coordinator.process().Wait(20).has_value());
  }
  CoordinatorProcess again(dir / "data", dir.path());
  EXPECT_EQ(Grep(again.process().log(), "activity restored: [0-9]+ task events, 1 workers").size(), 1u)
      << ReadFile(again.process().log());
  FarmClient client(again.address(), "");
  const photonfarm::v1::ListJobEventsResponse events = client.ListJobEvents(id);
  ASSERT_EQ(size_t(events.events_size()), events_before);
  EXPECT_EQ(events.events(events.events_size() - 1).kind(), "merged");
  const std::vector<photonfarm::v1::WorkerInfo> workers = client.ListWorkers();
  ASSERT_EQ(workers.size(), 1u);
  EXPECT_EQ(workers[0].worker_id(), "w1");
  EXPECT_EQ(workers[0].tasks_done(), 8u);
  EXPECT_GT(workers[0].photons_emitted(), 0u);
  EXPECT_FALSE(workers[0].busy());
  EXPECT_TRUE(workers[0].offline()) << "it left the farm (SIGTERM: LeaveFarm) and has not called since";
  EXPECT_GE(workers[0].seconds_since_seen(), 2.0) << "seen when the first life last saw it";
}

TEST(Visibility, WatchWithoutWorkersSaysSo) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string id = Submit(dir, coordinator.address(), JobArgs());
  // No worker: the watch would wait forever; it is stopped after a few seconds.
  const RunResult r =
      RunCommand({Binaries::Pf(), "watch", id, "--coordinator", coordinator.address()}, dir.path(), 4);
  EXPECT_NE(r.err.find("no worker has contacted the coordinator"), std::string::npos) << r.err;
}

TEST(Visibility, FarmImageHeaderDescribesTheJob) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  auto w1 = StartWorker(coordinator.address(), dir.path(), "w1");
  JobArgs job;
  job.seed = 11;
  const std::string id = Submit(dir, coordinator.address(), job);
  RunResult r = RunCommand({Binaries::Pf(), "watch", id, "-q", "-o", (dir / "farm.exr").string(),
                            "--coordinator", coordinator.address()},
                           dir.path(), 120);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // On a terminal (script(1) gives pf a pty) the progress line ends by erasing the rest of the
  // line: a line shorter than the one before leaves no stray characters.
  r = RunCommand({"/usr/bin/script", "-qfec",
                  Binaries::Pf() + " watch " + id + " --coordinator " + coordinator.address(), "/dev/null"},
                 dir.path(), 60);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("\r["), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\033[K"), std::string::npos) << r.out;
  r = RunCommand({Binaries::Pf(), "info", (dir / "farm.exr").string()}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  for (const char* line : {"seed        11", "settings.integrator photonmap", "settings.photons 2000",
                           "settings.k  20", "camera.eye", "scene", "version", "date", "size        32x32"})
    EXPECT_NE(r.out.find(line), std::string::npos) << line << "\n" << r.out;
}

TEST(Visibility, CleanCoordinatorRestartIsNoErrorForWorkers) {
  TestDir dir;
  auto coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path());
  const int port = coordinator->port();
  auto w1 = StartWorker(coordinator->address(), dir.path(), "w1");
  // The worker is parked in its long poll when the coordinator stops cleanly.
  ASSERT_TRUE(WaitUntil([&] { return !Grep(dir / "w1.log", "starting").empty(); }, 30));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  coordinator->process().Signal(SIGTERM);
  ASSERT_EQ(coordinator->process().Wait(30), 0);
  coordinator.reset();
  coordinator =
      std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::vector<std::string>{}, port);
  const std::string id = Submit(dir, coordinator->address(), JobArgs());
  const RunResult r = RunCommand({Binaries::Pf(), "watch", id, "-q", "--coordinator", coordinator->address()},
                                 dir.path(), 120);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(Grep(dir / "w1.log", " error ").empty()) << ReadFile(dir / "w1.log");
}

}  // namespace
}  // namespace pf::e2e
