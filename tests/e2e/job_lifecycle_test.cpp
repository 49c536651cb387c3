// `pf pause` / `pf resume` against a real coordinator and workers (docs/farm.md "Pausing a job"):
// a paused job starts no task while its leases in flight finish, resumes to the image of an
// unpaused run bit for bit, and stays paused across a coordinator restart.
#include <signal.h>

#include <chrono>
#include <thread>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

JobArgs LifecycleJob() {
  JobArgs job;
  job.rounds = 3;  // 12 tasks
  return job;
}

RunResult Pf(const TestDir& dir, const std::string& address, std::vector<std::string> args) {
  return RunCommand(Concat(Concat({Binaries::Pf()}, args), {"--coordinator", address}), dir.path(), 30);
}

bool AnyMidTask(const std::vector<fs::path>& logs) {
  for (const fs::path& log : logs)
    if (MidTask(log)) return true;
  return false;
}

TEST(JobLifecycle, APausedJobStartsNoTaskAndResumesToTheSameImage) {
  TestDir dir;
  const JobArgs job = LifecycleJob();
  ASSERT_EQ(RenderLocally(dir, job.ToFlags()).exit_code, 0);
  const Image reference = ReadImage(dir / "local.exr");

  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string id = SubmitJob(dir, coordinator.address(), job.ToFlags());
  ASSERT_FALSE(id.empty());
  std::vector<fs::path> logs;
  // Paced at 0.3 s a task, so that the pause lands while tasks are left.
  auto workers = StartTwoPatientWorkers(coordinator.address(), dir.path(), &logs, 0.3);
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, id) >= 1; }, 30));

  RunResult r = Pf(dir, coordinator.address(), {"pause", id});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(" paused:"), std::string::npos) << r.out;
  EXPECT_EQ(Grep(coordinator.process().log(), "job " + id + ": paused").size(), 1u);
  // The leases in flight finish (the coordinator holds none, no worker is mid-task); after that
  // nothing of the job is leased for a while.
  FarmClient client(coordinator.address(), "");
  ASSERT_TRUE(WaitUntil([&] { return client.GetJob(id).tasks_running() == 0 && !AnyMidTask(logs); }, 20));
  const std::vector<size_t> offsets = LineCounts(logs);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  EXPECT_TRUE(LeasedTasksSince(logs, offsets, id).empty()) << "a task started while the job was paused";
  const v1::JobStatus paused = client.GetJob(id);
  EXPECT_TRUE(paused.paused());
  EXPECT_LT(paused.tasks_done(), paused.tasks_total());
  r = Pf(dir, coordinator.address(), {"list"});
  EXPECT_NE(r.out.find("paused"), std::string::npos) << r.out;

  r = Pf(dir, coordinator.address(), {"resume", id});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(Grep(coordinator.process().log(), "job " + id + ": resumed").size(), 1u);
  const v1::JobStatus st = WaitForJob(client, id, 60);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_FALSE(st.paused());
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  EXPECT_EQ(st.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds)
      << "nothing lost or counted twice";
  for (const auto& [task, count] : MergedTaskCounts(logs, id)) EXPECT_EQ(count, 1) << "task " << task;
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(id)), reference));
}

TEST(JobLifecycle, APausedJobStaysPausedAcrossACoordinatorRestart) {
  TestDir dir;
  auto [coordinator, port, address, id] = StartCoordinatorWithJob(dir, {}, LifecycleJob().ToFlags());
  ASSERT_FALSE(id.empty());
  ASSERT_EQ(Pf(dir, address, {"pause", id}).exit_code, 0);
  coordinator->process().Signal(SIGTERM);
  ASSERT_TRUE(coordinator->process().Wait(20).has_value());
  coordinator =
      std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::vector<std::string>{}, port);

  auto worker = StartWorker(address, dir.path(), "w1");
  const fs::path log = dir / "w1.log";
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  EXPECT_TRUE(Grep(log, "leased job=").empty()) << "a task of the paused job started after the restart";
  FarmClient client(address, "");
  EXPECT_TRUE(client.GetJob(id).paused());

  ASSERT_EQ(Pf(dir, address, {"resume", id}).exit_code, 0);
  const v1::JobStatus st = WaitForJob(client, id, 60);
  EXPECT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  // A finished job cannot be paused: the answer names its state.
  const RunResult r = Pf(dir, address, {"pause", id});
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.err.find("FAILED_PRECONDITION"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("SUCCEEDED"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace pf::e2e
