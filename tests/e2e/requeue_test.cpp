// `pf requeue` against a real coordinator and workers (docs/farm.md "Requeueing a job"): a
// finished progressive job continued to more passes renders only the new passes and ends in the
// image of a job submitted with that many passes, bit for bit — also when the coordinator is
// kill -9'd between the requeue and the first lease; a cancelled job re-run renders only what it
// had not merged and ends in the full job's image; what cannot be requeued is refused with the
// field and the reason.
#include <signal.h>

#include <set>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

std::vector<std::string> ProgressiveFlags(int passes) {
  return {"--integrator", "photonmap",
          "--photons",    "3000",
          "--k",          "20",
          "--plan",       "progressive",
          "--passes",     std::to_string(passes),
          "--tile",       "16",
          "--spp",        "1",
          "--res",        "32x32",
          "--seed",       "9"};
}

RunResult Pf(const TestDir& dir, const std::string& address, std::vector<std::string> args) {
  return RunCommand(Concat(Concat({Binaries::Pf()}, args), {"--coordinator", address}), dir.path(), 60);
}

// The tasks of `job_id` the worker logs show leased.
std::set<uint64_t> Leased(const std::vector<fs::path>& logs, const std::string& job_id) {
  return LeasedTasksSince(logs, std::vector<size_t>(logs.size(), 0), job_id);
}

TEST(Requeue, AProgressiveJobContinuedToMorePassesIsTheLongerJobBitForBit) {
  TestDir dir;
  const Image reference = RenderLocallyToImage(dir, ProgressiveFlags(8));
  ASSERT_GT(PixelSum(reference), 0.0);
  auto coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path());
  const int port = coordinator->port();
  const std::string address = coordinator->address();
  const std::string first = SubmitJob(dir, address, ProgressiveFlags(4));
  ASSERT_FALSE(first.empty());
  std::vector<fs::path> logs;
  auto workers = StartTwoPatientWorkers(address, dir.path(), &logs);
  FarmClient client(address, "");
  v1::JobStatus st = WaitForJob(client, first, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  const uint64_t carried = st.tasks_done();
  ASSERT_EQ(carried, 16u) << "4 passes of 4 tiles";
  // No worker takes the new job before the coordinator's crash below.
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) ASSERT_TRUE(w->Wait(20).has_value());

  const RunResult r = Pf(dir, address, {"requeue", first.substr(0, 8), "--passes", "8"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string second = r.out.substr(0, r.out.find('\n'));
  ASSERT_EQ(second.size(), first.size()) << r.out;
  EXPECT_NE(r.err.find("16 merged tasks carried"), std::string::npos) << r.err;
  st = client.GetJob(second);
  EXPECT_EQ(st.spec().requeued_from(), first);
  EXPECT_EQ(st.spec().plan().progressive().passes(), 8u);
  EXPECT_EQ(st.tasks_done(), carried);
  EXPECT_EQ(st.tasks_queued(), 16u);

  // The carried results are the new job's own from the moment its id is known.
  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  coordinator =
      std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::vector<std::string>{}, port);
  EXPECT_FALSE(
      Grep(coordinator->process().log(), "job " + second + ": resumed \\(QUEUED\\): 16 tasks merged").empty())
      << ReadFile(coordinator->process().log());
  std::vector<fs::path> more_logs;
  workers = StartTwoPatientWorkers(address, dir.path(), &more_logs);
  st = WaitForJob(client, second, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  EXPECT_EQ(st.tasks_total(), 32u);
  // Only the new passes were rendered, each once.
  const std::set<uint64_t> leased = Leased(more_logs, second);
  EXPECT_EQ(leased.size(), 16u);
  for (uint64_t t : leased) EXPECT_GE(t, carried) << "carried task " << t << " rendered again";
  for (const auto& [task, count] : MergedTaskCounts(more_logs, second))
    EXPECT_EQ(count, 1) << "task " << task;
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(second)), reference));
  // The finished job is untouched: still 4 passes, and deleting it takes nothing from the new one.
  EXPECT_EQ(client.GetJob(first).spec().plan().progressive().passes(), 4u);
  ASSERT_EQ(Pf(dir, address, {"delete", first}).exit_code, 0);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(second)), reference));
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

TEST(Requeue, ACancelledJobReRunsOnlyWhatItHadNotMerged) {
  TestDir dir;
  JobArgs job;
  job.rounds = 4;  // 16 tasks
  ASSERT_EQ(RenderLocally(dir, job.ToFlags()).exit_code, 0);
  const Image reference = ReadImage(dir / "local.exr");
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string first = SubmitJob(dir, coordinator.address(), job.ToFlags());
  ASSERT_FALSE(first.empty());
  std::vector<fs::path> logs;
  auto workers = StartTwoPatientWorkers(coordinator.address(), dir.path(), &logs, 0.2);
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, first) >= 3; }, 60));
  ASSERT_EQ(Pf(dir, coordinator.address(), {"cancel", first}).exit_code, 0);
  FarmClient client(coordinator.address(), "");
  const v1::JobStatus cancelled = WaitForJob(client, first, 30);
  ASSERT_EQ(cancelled.state(), v1::JOB_STATE_CANCELLED);
  // The cancel drops the leases in flight (a late result is ignored): wait until it holds none.
  ASSERT_TRUE(WaitUntil([&] { return client.GetJob(first).tasks_running() == 0; }, 30));
  const uint64_t merged = client.GetJob(first).tasks_done();
  ASSERT_LT(merged, 16u) << "the job finished before the cancel";

  const RunResult r = Pf(dir, coordinator.address(), {"requeue", first});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string second = r.out.substr(0, r.out.find('\n'));
  const v1::JobStatus st = WaitForJob(client, second, 120);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_EQ(st.tasks_done(), 16u);
  EXPECT_EQ(Leased(logs, second).size(), 16u - merged) << "a merged task rendered again";
  EXPECT_EQ(st.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(second)), reference));
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

TEST(Requeue, WhatCannotBeRequeuedIsRefusedWithTheReason) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string address = coordinator.address();
  // No workers yet: the job stays queued.
  const std::string id = SubmitJob(dir, address, ProgressiveFlags(2));
  ASSERT_FALSE(id.empty());
  RunResult r = Pf(dir, address, {"requeue", id});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("only a succeeded, failed or cancelled job can be requeued"), std::string::npos)
      << r.err;

  auto worker = StartWorker(address, dir.path(), "w");
  FarmClient client(address, "");
  ASSERT_EQ(WaitForJob(client, id, 60).state(), v1::JOB_STATE_SUCCEEDED);
  r = Pf(dir, address, {"requeue", id});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("merged every task of its plan"), std::string::npos) << r.err;
  r = Pf(dir, address, {"requeue", id, "--passes", "1"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("extend_to: 1 is fewer than the job's 2 passes"), std::string::npos) << r.err;
  r = Pf(dir, address, {"requeue", id, "--maps", "4"});
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("give --passes"), std::string::npos) << r.err;
  r = Pf(dir, address, {"requeue", "0000"});
  EXPECT_EQ(r.exit_code, 3) << r.err;

  // A client cannot claim a job is a requeue.
  v1::JobSpec spec = client.GetJob(id).spec();
  spec.set_requeued_from(id);
  try {
    client.SubmitJob(spec);
    ADD_FAILURE() << "a spec with requeued_from was accepted";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_NE(std::string(e.what()).find("spec.requeued_from"), std::string::npos) << e.what();
  }
  worker->Signal(SIGTERM);
  EXPECT_TRUE(worker->Wait(20).has_value());
}

}  // namespace
}  // namespace pf::e2e
