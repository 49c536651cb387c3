// The progressive plan (Knaus & Zwicker 2011; common/plan/task_plan.h (e)) on a real farm: the
// passes travel as tasks whose estimates read each pass's radius, and the image is bit-identical to
// the single-process render of the same plan and seed (`pf render --local-only`) for 1 and 2
// workers, and it is not the multiple-maps image of the same maps (the radius query is used). The
// same holds with faults: a worker SIGKILLed mid-pass and the coordinator kill -9'd and restarted
// on its data dir lose and double-count nothing (each task merged once, the image bit-identical).
// Its stop rules: --target-error (the bias indicator, common/plan/progressive_bias.h) locally and
// on the farm, a missed target said by the job, and the target refused where it cannot be judged.
#include <signal.h>

#include <cstdlib>
#include <set>

#include "client/farm_client.h"
#include "common/image/exr_io.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

// The same job under `plan`, whose number of maps is given by `count_flag` (--passes for the
// progressive plan, --maps for multiple maps).
std::vector<std::string> Flags(const std::string& plan, const std::string& count_flag) {
  return {"--integrator", "photonmap", "--photons", "2000", "--k",   "20",    "--plan", plan, count_flag, "3",
          "--tile",       "16",        "--spp",     "1",    "--res", "33x33", "--seed", "5"};
}

TEST(ProgressiveFarm, BitIdenticalForOneTwoAndThreeWorkersAndLocal) {
  TestDir dir;
  const std::vector<std::string> flags = Flags("progressive", "--passes");
  const Image reference = RenderLocallyToImage(dir, flags);
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";
  ExpectLocalFarmsBitIdentical(dir, flags, reference, {1, 2, 3}, "farm-");
  EXPECT_FALSE(BitIdentical(RenderLocallyToImage(dir, Flags("multiple-maps", "--maps")), reference))
      << "the progressive passes rendered like multiple maps";
}

// Passes long enough to be caught mid-flight: 8 passes of 20000 photons, 4 tiles each.
std::vector<std::string> FaultFlags() {
  return {"--integrator", "photonmap",   "--photons", "20000", "--k",    "20",
          "--plan",       "progressive", "--passes",  "8",     "--tile", "24",
          "--spp",        "2",           "--res",     "48x48", "--seed", "11"};
}

TEST(ProgressiveFarm, AKilledWorkerAndACoordinatorRestartLoseAndDoubleNothing) {
  namespace v1 = photonfarm::v1;
  TestDir dir;
  const Image reference = RenderLocallyToImage(dir, FaultFlags());
  ASSERT_GT(PixelSum(reference), 0.0);
  auto [coordinator, port, address, job_id] =
      StartCoordinatorWithJob(dir, {"--lease-seconds", "2", "--max-attempts", "10"}, FaultFlags());
  ASSERT_FALSE(job_id.empty());
  std::vector<std::filesystem::path> logs;
  // Two workers pausing 0.1 s before each render task keep the job running long enough for both
  // faults, however fast the machine; a third is SIGKILLed while it holds a lease.
  std::vector<std::unique_ptr<Process>> workers = StartTwoPatientWorkers(address, dir.path(), &logs, 0.1);
  workers.push_back(StartWorker(address, dir.path(), "victim", {"--report-retry", "30"}));
  logs.push_back(dir / "victim.log");
  Process* victim = workers.back().get();
  ASSERT_TRUE(WaitUntil([&] { return MidTask(victim->log()); }, 60)) << ReadFile(victim->log());
  victim->Signal(SIGKILL);
  victim->Wait(5);

  // Then the coordinator, once some passes' tasks are merged.
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, job_id) >= 6; }, 120));
  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  const std::map<uint64_t, int> before = MergedTaskCounts(logs, job_id);
  const std::vector<size_t> offsets = LineCounts(logs);
  coordinator = std::make_unique<CoordinatorProcess>(
      dir / "data", dir.path(), std::vector<std::string>{"--lease-seconds", "2", "--max-attempts", "10"},
      port);
  EXPECT_FALSE(Grep(coordinator->process().log(), "resumed").empty())
      << ReadFile(coordinator->process().log());

  FarmClient client(address, "");
  const v1::JobStatus st = WaitForJob(client, job_id, 240);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_LT(before.size(), st.tasks_total()) << "the job finished before the coordinator crash";
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  // No task acknowledged before the crash ran again after it, none was acknowledged twice.
  const std::set<uint64_t> leased_after = LeasedTasksSince(logs, offsets, job_id);
  for (const auto& [task, count] : before)
    EXPECT_FALSE(leased_after.count(task)) << "task " << task << " re-run";
  for (const auto& [task, count] : MergedTaskCounts(logs, job_id)) EXPECT_EQ(count, 1) << "task " << task;
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  std::printf("victim killed after %zu leases; crash after %zu merged tasks; %zu leased after; %llu in all\n",
              Grep(victim->log(), "leased job=").size(), before.size(), leased_after.size(),
              (unsigned long long)st.tasks_total());
  for (auto& w : workers)
    if (w.get() != victim) w->Signal(SIGTERM);
  for (auto& w : workers) {
    if (w.get() != victim) {
      EXPECT_TRUE(w->Wait(20).has_value()) << w->name();
    }
  }
}

// The progressive job of the stop-rule tests, with `extra` flags; written to dir/<name>.
std::vector<std::string> TargetRender(const TestDir& dir, const std::string& name,
                                      const std::vector<std::string>& extra) {
  return Concat({Binaries::Pf(),
                 "render",
                 Binaries::Scene(),
                 "--integrator",
                 "photonmap",
                 "--photons",
                 "2000",
                 "--plan",
                 "progressive",
                 "--tile",
                 "32",
                 "--spp",
                 "1",
                 "--res",
                 "48x48",
                 "--seed",
                 "5",
                 "-o",
                 (dir / name).string(),
                 "--no-png",
                 "-q"},
                extra);
}

double MetaNumber(const ImageMetadata& meta, const std::string& key) {
  const auto it = meta.find(key);
  if (it == meta.end()) {
    ADD_FAILURE() << "no header key " << key;
    return -1;
  }
  return std::strtod(it->second.c_str(), nullptr);
}

// The error estimate of the stop-rule job after 16 passes, rendered in this process (-1 and a
// failure if pf failed).
double ErrorAfter16Passes(const TestDir& dir) {
  const RunResult r =
      RunCommand(Concat(TargetRender(dir, "p16.exr", {"--passes", "16"}), {"--local-only"}), dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  if (r.exit_code != 0) return -1;
  ImageMetadata meta;
  ReadExr(dir / "p16.exr", &meta);
  return MetaNumber(meta, "estimate.error_rms");
}

TEST(ProgressiveStop, TargetErrorStopsLocallyAtTheImageOfThatManyPasses) {
  TestDir dir;
  // The error estimate after 16 passes, as the target: the open-ended render must reach it by then.
  const double target = ErrorAfter16Passes(dir);
  ASSERT_GT(target, 0.0);
  RunResult r =
      RunCommand(Concat(TargetRender(dir, "t.exr", {"--target-error", std::to_string(target * 1.0001)}),
                        {"--local-only"}),
                 dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  ImageMetadata meta;
  const Image stopped = ReadExr(dir / "t.exr", &meta);
  EXPECT_EQ(meta["stop.stopped_by"], "targets met");
  EXPECT_EQ(meta["stop.targets_met"], "yes");
  EXPECT_LE(MetaNumber(meta, "estimate.error_rms"), target * 1.0001);
  const int passes = std::atoi(meta["stop.units_done"].c_str());
  EXPECT_GE(passes, 8);  // the bias fit's minimum (kMinPassesForBias)
  EXPECT_LE(passes, 16);
  EXPECT_NE(meta["plan"].find("passes=" + std::to_string(passes)), std::string::npos) << meta["plan"];
  // The image is exactly the plan with that many passes.
  r = RunCommand(Concat(TargetRender(dir, "n.exr", {"--passes", std::to_string(passes)}), {"--local-only"}),
                 dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(BitIdentical(ReadImage(dir / "n.exr"), stopped));
}

TEST(ProgressiveStop, FarmJobMeetsItsTargetOrSaysItMissedIt) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  auto worker = StartWorker(coordinator.address(), dir.path(), "w1");
  FarmClient client(coordinator.address(), "");
  // Reachable: the error after 16 passes of the same job (rendered here).
  const double target = ErrorAfter16Passes(dir);
  const std::vector<std::string> job = {"--integrator", "photonmap", "--photons", "2000",  "--plan",
                                        "progressive",  "--tile",    "32",        "--spp", "1",
                                        "--res",        "48x48",     "--seed",    "5"};
  const std::string met =
      SubmitJob(dir, coordinator.address(), Concat(job, {"--target-error", std::to_string(target * 1.0001)}));
  ASSERT_FALSE(met.empty());
  const auto st = WaitForJob(client, met, 240);
  EXPECT_EQ(st.state(), photonfarm::v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_GE(st.estimated_error_rms(), 0.0);
  EXPECT_LE(st.estimated_error_rms(), target * 1.0001);
  EXPECT_GE(st.estimated_bias_rms(), 0.0);
  EXPECT_GT(st.tasks_cancelled(), 0u) << "the open-ended job ran all its passes";
  EXPECT_EQ(st.target_missed(), "");
  // Unreachable in 8 passes: the job succeeds with its image and says what it reached.
  const std::string missed =
      SubmitJob(dir, coordinator.address(), Concat(job, {"--passes", "8", "--target-error", "1e-9"}));
  ASSERT_FALSE(missed.empty());
  const auto st2 = WaitForJob(client, missed, 240);
  EXPECT_EQ(st2.state(), photonfarm::v1::JOB_STATE_SUCCEEDED) << st2.failure_reason();
  EXPECT_NE(st2.target_missed().find("above target 1e-09"), std::string::npos) << st2.target_missed();
  std::string logs;
  for (const auto& entry : std::filesystem::directory_iterator(dir.path()))
    if (entry.path().filename().string().starts_with("coordinator-")) logs += ReadFile(entry.path());
  EXPECT_NE(logs.find("target not met"), std::string::npos);
}

TEST(ProgressiveStop, TargetErrorIsRefusedWhereItCannotBeJudged) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::vector<std::string> multiple = {"--integrator", "photonmap",     "--photons",      "2000",
                                             "--plan",       "multiple-maps", "--maps",         "4",
                                             "--res",        "16x16",         "--target-error", "0.01"};
  const RunResult farm = RunCommand(
      Concat({Binaries::Pf(), "submit", Binaries::Scene(), "--coordinator", coordinator.address()}, multiple),
      dir.path());
  EXPECT_EQ(farm.exit_code, 3) << farm.err;
  EXPECT_NE(farm.err.find("spec.stop.target_error_rms: needs the progressive plan"), std::string::npos)
      << farm.err;
  const RunResult local =
      RunCommand(Concat(Concat({Binaries::Pf(), "render", Binaries::Scene()}, multiple),
                        {"--local-only", "-o", (dir / "m.exr").string(), "--no-png", "-q"}),
                 dir.path());
  EXPECT_EQ(local.exit_code, 3) << local.err;
  EXPECT_NE(local.err.find("target_error_rms: needs the progressive plan"), std::string::npos) << local.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "m.exr"));
  // Without --plan, a target error gives the photon map's farm job the progressive plan, not auto's.
  const std::string id = SubmitJob(
      dir, coordinator.address(),
      {"--integrator", "photonmap", "--photons", "2000", "--res", "16x16", "--target-error", "0.01"});
  ASSERT_FALSE(id.empty());
  FarmClient client(coordinator.address(), "");
  const auto st = client.GetJob(id);
  EXPECT_TRUE(st.spec().plan().has_progressive()) << st.spec().plan().DebugString();
  EXPECT_EQ(st.spec().plan().progressive().passes(), 1024u);
}

TEST(ProgressiveStop, PlainRenderWithABudgetRunsTheConsistentPlanOpenEnded) {
  TestDir dir;
  const RunResult r = RunCommand(
      {Binaries::Pf(), "render", Binaries::Scene(), "--integrator", "photonmap", "--photons", "2000", "--res",
       "24x24", "--spp", "1", "--time-budget", "1", "-o", (dir / "b.exr").string(), "--no-png"},
      dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("plan progressive: chosen for the budget"), std::string::npos) << r.err;
  ImageMetadata meta;
  ReadExr(dir / "b.exr", &meta);
  EXPECT_EQ(meta["stop.stopped_by"], "time budget");
  EXPECT_EQ(meta["plan"].rfind("progressive passes=", 0), 0u) << meta["plan"];
  EXPECT_NE(meta["plan"], "progressive passes=1024 spp=1 tile=64");
}

}  // namespace
}  // namespace pf::e2e
