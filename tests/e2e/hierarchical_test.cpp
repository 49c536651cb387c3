// The hierarchical plan (Wald 1999, §4.5; issue #13) on a real farm: the coordinator creates the
// localization tasks from merged results, and the image is bit-identical to the single-process
// render of the same plan and seed (`pf render --local-only`)
//  (a) for 1, 2 and 3 workers started by `pf render --workers N`;
//  (b) with a worker SIGKILLed mid-task and the coordinator SIGKILLed and restarted mid-job.
#include <signal.h>

#include <algorithm>
#include <thread>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// Cornell box 33×33, 2-D hierarchy L = 3 (level-0 points every 8 pixels), n_l = 4, 2, 1, 1;
// rows per task 8. Its walls' edges make the coordinator localize some pixels.
std::vector<std::string> HierarchicalFlags(int photons) {
  return {"--integrator",
          "photonmap",
          "--photons",
          std::to_string(photons),
          "--k",
          "20",
          "--plan",
          "hierarchical",
          "--levels",
          "3",
          "--dims",
          "2",
          "--base-samples",
          "4",
          "--min-samples",
          "1",
          "--tile",
          "8",
          "--spp",
          "1",
          "--res",
          "33x33",
          "--seed",
          "11"};
}

Image LocalReference(const TestDir& dir, const std::vector<std::string>& flags) {
  const RunResult r = RenderLocally(dir, flags);
  EXPECT_EQ(r.exit_code, 0) << r.err;
  return ReadImage(dir / "local.exr");
}

TEST(HierarchicalFarm, BitIdenticalForOneTwoThreeWorkersAndLocal) {
  TestDir dir;
  const std::vector<std::string> flags = HierarchicalFlags(2000);
  const Image reference = LocalReference(dir, flags);
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";
  for (int workers : {1, 2, 3}) {
    const std::string out = (dir / ("farm-" + std::to_string(workers) + ".exr")).string();
    const RunResult r = RunCommand(
        Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, flags),
               {"--workers", std::to_string(workers), "--threads", "1", "-o", out, "--no-png", "-q"}),
        dir.path());
    ASSERT_EQ(r.exit_code, 0) << "workers=" << workers << "\n" << r.err;
    EXPECT_TRUE(BitIdentical(ReadImage(out), reference)) << "workers=" << workers;
  }
}

TEST(HierarchicalFarm, KilledWorkerAndCoordinatorRestartGiveTheLocalImage) {
  TestDir dir;
  const std::vector<std::string> flags = HierarchicalFlags(40000);  // tasks of ~0.1-0.3 s
  const Image reference = LocalReference(dir, flags);
  const std::vector<std::string> coordinator_args = {"--lease-seconds", "2", "--max-attempts", "10"};
  auto coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), coordinator_args);
  const int port = coordinator->port();
  const std::string address = coordinator->address();
  const RunResult sub = RunCommand(
      Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, flags), {"--coordinator", address}),
      dir.path());
  ASSERT_EQ(sub.exit_code, 0) << sub.err;
  std::string job_id = sub.out;
  while (!job_id.empty() && (job_id.back() == '\n' || job_id.back() == ' ')) job_id.pop_back();
  {
    FarmClient client(address, "");
    EXPECT_EQ(client.GetJob(job_id).tasks_total(), 40u) << "every level's detail tasks from the start";
  }

  // A victim, SIGKILLed while it holds a lease.
  std::unique_ptr<Process> victim = StartWorker(address, dir.path(), "victim");
  ASSERT_TRUE(WaitUntil([&] { return MidTask(victim->log()); }, 60)) << ReadFile(victim->log());
  victim->Signal(SIGKILL);
  victim->Wait(5);

  std::vector<fs::path> logs;
  std::vector<std::unique_ptr<Process>> workers = StartTwoPatientWorkers(address, dir.path(), &logs);
  // The coordinator crashes once a few tasks are merged (the job has 40 static tasks).
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, job_id) >= 12; }, 120));
  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), coordinator_args, port);
  EXPECT_FALSE(Grep(coordinator->process().log(), "resumed \\(RUNNING\\)").empty())
      << "the crash came after the job ended\n"
      << ReadFile(coordinator->process().log());

  FarmClient client(address, "");
  const v1::JobStatus st = WaitForJob(client, job_id, 180);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  // Localization tasks were created (by the first or the restarted coordinator) beyond the 40
  // static ones.
  EXPECT_GT(st.tasks_total(), 40u);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

TEST(HierarchicalFarm, BadHierarchicalJobsAreRejectedNamingTheField) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::vector<std::string> base =
      Concat({Binaries::Pf(), "submit", Binaries::Scene(), "--coordinator", coordinator.address()},
             HierarchicalFlags(1000));
  const RunResult ok = RunCommand(base, dir.path());
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
  const std::vector<std::pair<std::vector<std::string>, std::string>> bad = {
      {{"--levels", "0"}, "spec.plan.hierarchical.levels"},
      {{"--dims", "3"}, "spec.plan.hierarchical.dims"},
      {{"--min-samples", "9"}, "spec.plan.hierarchical.min_samples"},
      {{"--decay", "0.5"}, "spec.plan.hierarchical.decay"},
      {{"--target-noise", "0.01"}, "spec.stop.target_noise_rms"},
      {{"--max-rounds", "2"}, "spec.stop.max_rounds"}};
  for (const auto& [flags, field] : bad) {
    std::vector<std::string> argv = base;  // the flag's value replaced, or the flag added
    const auto it = std::find(argv.begin(), argv.end(), flags[0]);
    if (it == argv.end())
      argv = Concat(argv, flags);
    else
      *(it + 1) = flags[1];
    const RunResult r = RunCommand(argv, dir.path());
    EXPECT_EQ(r.exit_code, 3) << flags[0] << "\n" << r.err;
    EXPECT_NE(r.err.find(field), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace pf::e2e
