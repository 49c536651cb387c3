// Faults with real processes:
//  (b) workers SIGKILLed mid-task, repeatedly, and one SIGSTOPped (hung with its connection
//      open: only lease expiry can reclaim its task): the job completes, the image is
//      bit-identical to the local render, and every task was merged exactly once;
//  (c) the coordinator kill -9'd mid-job and restarted on the same data dir (and port): the job
//      resumes, tasks merged before the crash are not run again, the image is bit-identical;
//  (d) a flaky worker that fails every task in milliseconds next to a real one: blocklisted for
//      the job after 3 failed attempts, the image is the clean run's, bit for bit.
#include <signal.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <optional>
#include <regex>
#include <set>
#include <thread>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// Tasks long enough to be caught mid-flight (~0.2-0.5 s each on one thread), few enough to
// keep the test short.
JobArgs SlowJob() {
  JobArgs job;
  job.photons = 60000;
  job.k = 50;
  job.stride = 2;
  job.rounds = 4;  // 16 tasks
  job.spp = 2;
  return job;
}

Image LocalReference(const TestDir& dir, const JobArgs& job) {
  const RunResult r = RenderLocally(dir, job.ToFlags());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return ReadImage(dir / "local.exr");
}

TEST(FarmFaults, KilledAndHungWorkersLoseOnlyTheirLeases) {
  TestDir dir;
  const JobArgs job = SlowJob();
  const Image reference = LocalReference(dir, job);
  CoordinatorProcess coordinator(dir / "data", dir.path(),
                                 {"--lease-seconds", "1.5", "--max-attempts", "10"});
  const std::string job_id = SubmitJob(dir, coordinator.address(), job.ToFlags());
  ASSERT_FALSE(job_id.empty());

  std::vector<fs::path> logs;
  std::vector<std::unique_ptr<Process>> workers;
  auto start = [&](const std::string& id) {
    workers.push_back(StartWorker(coordinator.address(), dir.path(), id));
    logs.push_back(dir / (id + ".log"));
    return workers.back().get();
  };

  // The hung one: SIGSTOP once it holds a lease. Its connection stays open, it never answers.
  Process* hung = start("hung");
  ASSERT_TRUE(WaitUntil([&] { return MidTask(hung->log()); }, 30)) << ReadFile(hung->log());
  hung->Signal(SIGSTOP);

  // Three victims, each SIGKILLed mid-task; a survivor finishes the job.
  int kills = 0;
  for (int i = 0; i < 3; ++i) {
    Process* victim = start("victim-" + std::to_string(i));
    // Kill it while it builds its photon map or renders (tasks take 0.1-0.5 s here).
    const bool caught = WaitUntil(
        [&] {
          if (!MidTask(victim->log())) return false;
          std::this_thread::sleep_for(std::chrono::milliseconds(60));
          return MidTask(victim->log());
        },
        30);
    if (!caught) break;
    victim->Signal(SIGKILL);
    victim->Wait(5);
    ++kills;
  }
  EXPECT_EQ(kills, 3);
  start("survivor-1");
  start("survivor-2");

  FarmClient client(coordinator.address(), "");
  const v1::JobStatus st = WaitForJob(client, job_id, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();

  // The hung worker wakes up: its late result must be ignored (merged=false), never merged.
  hung->Signal(SIGCONT);
  WaitUntil([&] { return !Grep(hung->log(), "completed job=").empty(); }, 10);
  EXPECT_TRUE(Grep(hung->log(), "merged=true").empty()) << ReadFile(hung->log());

  // Accounting: every task merged exactly once, samples = pixels x spp x rounds.
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  EXPECT_EQ(st.tasks_total(), uint64_t(job.rounds * job.stride * job.stride));
  EXPECT_EQ(st.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds);
  const std::map<uint64_t, int> merged = MergedTaskCounts(logs, job_id);
  // Workers log each merge they saw; a victim killed right after its result was merged never
  // logs it, so the workers' logs may miss such tasks, but never show one twice.
  EXPECT_LE(merged.size(), st.tasks_total());
  for (const auto& [task, count] : merged) EXPECT_EQ(count, 1) << "task " << task;
  // The coordinator's own record agrees: each task merged once.
  const fs::path coordinator_log = coordinator.process().log();
  for (uint64_t t = 0; t < st.tasks_total(); ++t)
    EXPECT_EQ(Grep(coordinator_log, "job " + job_id + " task " + std::to_string(t) + ": merged ").size(), 1u)
        << "task " << t;
  // Leases were lost: the hung worker's task and each killed worker's task were leased again
  // (attempt > 1). A victim whose result the coordinator merged in the instant before SIGKILL
  // (it dies before logging it) lost nothing, so its task is not retried: counted from the
  // coordinator's log, which names the worker of each merge.
  int merged_before_kill = 0;
  for (int i = 0; i < kills; ++i)
    if (!Grep(coordinator_log, "merged \\(attempt [0-9]+, worker victim-" + std::to_string(i) + ";").empty())
      ++merged_before_kill;
  size_t retried = 0;
  for (const fs::path& log : logs) retried += Grep(log, "leased job=.* attempt=[2-9]").size();
  EXPECT_GE(retried, size_t(1 + kills - merged_before_kill));

  const std::string bytes = client.GetImage(job_id);
  EXPECT_TRUE(BitIdentical(DecodeImage(bytes), reference));
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value()) << w->name();
}

// The hostile farm (docs/farm.md, "Worker health"): a worker answering every task with
// FailTask(retryable) in milliseconds while a real worker is busy rendering. It used up a task's 3
// attempts in ~5 ms and the job FAILED; now it is blocklisted for the job after 3 failed attempts
// (pf status, pf events, pf workers show it), the real worker renders every task, and the image
// equals the clean local run bit for bit.
TEST(FarmFaults, AFlakyWorkerIsBlocklistedAndTheImageEqualsACleanRun) {
  TestDir dir;
  const JobArgs job = SlowJob();
  const Image reference = LocalReference(dir, job);
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string job_id = SubmitJob(dir, coordinator.address(), job.ToFlags());
  ASSERT_FALSE(job_id.empty());
  // The real worker first: the coordinator must know a live worker besides the flaky one.
  auto real = StartWorker(coordinator.address(), dir.path(), "real");
  ASSERT_TRUE(WaitUntil([&] { return MidTask(real->log()); }, 30)) << ReadFile(real->log());
  Process flaky("flaky",
                {Binaries::FakeWorker(), "--coordinator", coordinator.address(), "--mode", "flaky",
                 "--worker-id", "flaky", "--seconds", "3"},
                dir / "flaky.log", dir / "flaky.json");
  FarmClient client(coordinator.address(), "");
  const v1::JobStatus st = WaitForJob(client, job_id, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  ASSERT_EQ(flaky.Wait(30).value_or(-1), 0) << ReadFile(dir / "flaky.log");
  const nlohmann::json out = nlohmann::json::parse(ReadFile(dir / "flaky.json"));
  EXPECT_EQ(out.at("failures").get<int>(), 3)
      << out.dump() << ": blocklisted after 3, then nothing of this job";
  ASSERT_EQ(st.blocklisted_workers_size(), 1);
  EXPECT_EQ(st.blocklisted_workers(0).worker_id(), "flaky");
  EXPECT_EQ(st.blocklisted_workers(0).failed_attempts(), 3u);
  const std::vector<std::string> at = {"--coordinator", coordinator.address()};
  RunResult r = RunCommand(Concat({Binaries::Pf(), "events", job_id}, at), dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(std::regex_search(r.out, std::regex("blocklisted +[0-9]+ +[0-9]+ +flaky"))) << r.out;
  r = RunCommand(Concat({Binaries::Pf(), "workers", "--json"}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  bool listed = false;
  for (const nlohmann::json& w : nlohmann::json::parse(r.out))
    if (w.at("worker_id") == "flaky") listed = w.at("blocklisted_job_ids") == nlohmann::json::array({job_id});
  EXPECT_TRUE(listed) << r.out;
  EXPECT_EQ(Grep(real->log(), "failed job=").size(), 0u);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  real->Signal(SIGTERM);
  EXPECT_EQ(real->Wait(20).value_or(-1), 0);
}

// Worker health as pf workers shows it (docs/farm.md "Worker health"): a worker stopped with
// SIGTERM says it leaves and is listed offline, never lost; a SIGKILLed one is listed lost within
// two lease periods of the kill.
TEST(FarmFaults, AStoppedWorkerIsOfflineAndAKilledOneIsLostWithinTwoLeases) {
  TestDir dir;
  constexpr double kLease = 2;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--lease-seconds", "2"});
  FarmClient client(coordinator.address(), "");
  auto stopped = StartWorker(coordinator.address(), dir.path(), "w-stopped");
  auto killed = StartWorker(coordinator.address(), dir.path(), "w-killed");
  const auto info = [&](const std::string& id) -> std::optional<v1::WorkerInfo> {
    for (const v1::WorkerInfo& w : client.ListWorkers())
      if (w.worker_id() == id) return w;
    return std::nullopt;
  };
  ASSERT_TRUE(WaitUntil([&] { return info("w-stopped") && info("w-killed"); }, 30));
  stopped->Signal(SIGTERM);
  EXPECT_EQ(stopped->Wait(20).value_or(-1), 0);
  killed->Signal(SIGKILL);
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(WaitUntil(
      [&] {
        const std::optional<v1::WorkerInfo> w = info("w-killed");
        return w && w->lost();
      },
      4 * kLease));
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Two lease periods after the coordinator last heard from it (its open long poll counted until
  // the kill closed it), plus this test's polling: not before, and not much after.
  EXPECT_GE(seconds, 2 * kLease - 0.3) << "lost after " << seconds << " s";
  EXPECT_LE(seconds, 2 * kLease + 2) << "lost after " << seconds << " s";
  std::printf("the SIGKILLed worker was listed lost %.2f s after the kill (lease %.0f s)\n", seconds, kLease);
  std::this_thread::sleep_for(std::chrono::duration<double>(2 * kLease));
  const std::optional<v1::WorkerInfo> stopped_info = info("w-stopped");
  ASSERT_TRUE(stopped_info.has_value());
  EXPECT_TRUE(stopped_info->offline());
  EXPECT_FALSE(stopped_info->lost()) << "it said it was leaving";
  const RunResult r =
      RunCommand({Binaries::Pf(), "workers", "--coordinator", coordinator.address()}, dir.path());
  EXPECT_TRUE(std::regex_search(r.out, std::regex("w-stopped +\\S+ +[0-9]+ +offline"))) << r.out;
  EXPECT_TRUE(std::regex_search(r.out, std::regex("w-killed +\\S+ +[0-9]+ +lost"))) << r.out;
}

TEST(FarmFaults, CoordinatorCrashResumesWithoutRerunningMergedTasks) {
  TestDir dir;
  JobArgs job = SlowJob();
  job.rounds = 5;  // 20 tasks
  const Image reference = LocalReference(dir, job);
  auto [coordinator, port, address, job_id] =
      StartCoordinatorWithJob(dir, {"--lease-seconds", "3"}, job.ToFlags());
  ASSERT_FALSE(job_id.empty());
  std::vector<fs::path> logs;
  std::vector<std::unique_ptr<Process>> workers = StartTwoPatientWorkers(address, dir.path(), &logs, 0.1);

  // Crash once a third of the tasks are merged.
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, job_id) >= 7; }, 120));
  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  // What was acknowledged before the crash, and where each log stands.
  const std::map<uint64_t, int> before = MergedTaskCounts(logs, job_id);
  const std::vector<size_t> offsets = LineCounts(logs);
  EXPECT_LT(before.size(), size_t(job.rounds * job.stride * job.stride))
      << "the job finished before the crash";

  // Restart on the same data dir and port; the workers reconnect by themselves.
  coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path(),
                                                     std::vector<std::string>{"--lease-seconds", "3"}, port);
  EXPECT_FALSE(Grep(coordinator->process().log(), "resumed").empty())
      << ReadFile(coordinator->process().log());
  FarmClient client(address, "");
  const v1::JobStatus st = WaitForJob(client, job_id, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();

  // No task acknowledged before the crash was leased again after it.
  const std::set<uint64_t> leased_after = LeasedTasksSince(logs, offsets, job_id);
  for (const auto& [task, count] : before)
    EXPECT_FALSE(leased_after.count(task)) << "task " << task << " re-run";
  // No task acknowledged twice over both coordinator lives. (A result made durable just before
  // the crash, whose acknowledgement was lost, is merged but logged merged=false by its worker:
  // hence "at most once" per log line, and the exact sample count proves nothing was doubled.)
  const std::map<uint64_t, int> merged = MergedTaskCounts(logs, job_id);
  EXPECT_GE(merged.size() + logs.size(), st.tasks_total());
  for (const auto& [task, count] : merged) EXPECT_EQ(count, 1) << "task " << task;
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  EXPECT_EQ(st.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  std::printf("crash after %zu merged tasks; %zu tasks leased after the restart; %llu tasks in all\n",
              before.size(), leased_after.size(), (unsigned long long)st.tasks_total());
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

TEST(FarmFaults, WorkerSigtermHandsBackOrFinishesItsTask) {
  TestDir dir;
  JobArgs job;
  job.photons = 1000000;  // ~1-2 s per task on one thread
  job.stride = 1;
  job.rounds = 3;  // 3 whole-image tasks
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string job_id = SubmitJob(dir, coordinator.address(), job.ToFlags());

  // --grace 0: SIGTERM mid-task hands the lease back at once (FailTask, retryable) and exits 0.
  auto quick = StartWorker(coordinator.address(), dir.path(), "quick", {"--grace", "0"});
  ASSERT_TRUE(WaitUntil([&] { return MidTask(quick->log()); }, 30));
  const auto t0 = std::chrono::steady_clock::now();
  quick->Signal(SIGTERM);
  EXPECT_EQ(quick->Wait(5).value_or(-1), 0) << ReadFile(quick->log());
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
  EXPECT_FALSE(Grep(quick->log(), "handed-back job=" + job_id).empty()) << ReadFile(quick->log());
  EXPECT_TRUE(
      WaitUntil([&] { return !Grep(coordinator.process().log(), "shutting down.*re-queued").empty(); }, 5))
      << ReadFile(coordinator.process().log());

  // Default grace: SIGTERM mid-task finishes and reports the task, then exits 0.
  auto patient = StartWorker(coordinator.address(), dir.path(), "patient");
  ASSERT_TRUE(WaitUntil([&] { return MidTask(patient->log()); }, 30));
  patient->Signal(SIGTERM);
  EXPECT_EQ(patient->Wait(30).value_or(-1), 0) << ReadFile(patient->log());
  EXPECT_EQ(Grep(patient->log(), "completed job=" + job_id + " .* merged=true").size(), 1u)
      << ReadFile(patient->log());
  EXPECT_EQ(Grep(patient->log(), "leased job=").size(), 1u) << "no new lease after SIGTERM";

  // The task handed back is done by the next worker; the job completes.
  auto last = StartWorker(coordinator.address(), dir.path(), "last");
  FarmClient client(coordinator.address(), "");
  const v1::JobStatus st = WaitForJob(client, job_id, 60);
  EXPECT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_EQ(st.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds);
  last->Signal(SIGTERM);
  EXPECT_EQ(last->Wait(20).value_or(-1), 0);
}

}  // namespace
}  // namespace pf::e2e
