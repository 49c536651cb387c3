// The hierarchical plan (Wald 1999, §4.5) on a real farm: the coordinator creates the
// localization tasks from merged results, and the image is bit-identical to the single-process
// render of the same plan and seed (`pf render --local-only`)
//  (a) for 1, 2 and 3 workers started by `pf render --workers N`;
//  (b) with a worker SIGKILLed mid-task and the coordinator SIGKILLed and restarted mid-job;
//  (c) both at once with three workers, the coordinator killed in the middle of a level.
#include <signal.h>

#include <algorithm>
#include <initializer_list>
#include <regex>
#include <set>
#include <thread>

#include "client/farm_client.h"
#include "common/plan/hierarchical.h"
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

TEST(HierarchicalFarm, BitIdenticalForOneTwoThreeWorkersAndLocal) {
  TestDir dir;
  const std::vector<std::string> flags = HierarchicalFlags(2000);
  const Image reference = RenderLocallyToImage(dir, flags);
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";
  ExpectLocalFarmsBitIdentical(dir, flags, reference, {1, 2, 3}, "farm-");
}

// --hier-part indirect (common/plan/hierarchical.h, "Parts"): the emission + direct light tasks
// and the map-part levels travel with their part (Task.part) and merge into the same image as
// the local render, for any worker count; and the split differs from the whole-radiance plan
// (the flag reaches the workers).
TEST(HierarchicalFarm, IndirectPartBitIdenticalForOneAndThreeWorkersAndLocal) {
  TestDir dir;
  std::vector<std::string> flags = HierarchicalFlags(2000);
  const Image whole = RenderLocallyToImage(dir, flags);
  flags.insert(flags.end(), {"--hier-part", "indirect", "--hier-direct-samples", "2"});
  const Image reference = RenderLocallyToImage(dir, flags);
  ASSERT_GT(PixelSum(reference), 0.0) << "the reference image is black";
  EXPECT_FALSE(BitIdentical(whole, reference));
  // Both estimate the same radiance: summed over the pixels that are not the light (below 2 in
  // both images; the light's pixels are ~100x brighter, and the sub-pixel noise of its edge at
  // 2 samples per pixel would dominate a plain sum) they agree to 10 % (two renders of
  // 2000-photon maps); a part dropped or doubled on the way (Task.part lost) would be off by its
  // share of the light, emission + direct light or the photon-map part, each far above 10 % here.
  auto unlit_sum = [](const Image& a, const Image& b) {
    double sum = 0;
    for (size_t p = 0; p < a.size(); ++p)
      if (a[p].Mean() < 2.0f && b[p].Mean() < 2.0f) sum += a[p].Mean();
    return sum;
  };
  EXPECT_NEAR(unlit_sum(reference, whole) / unlit_sum(whole, reference), 1.0, 0.1);
  ExpectLocalFarmsBitIdentical(dir, flags, reference, {1, 3}, "farm-indirect-");
}

// A worker SIGKILLed mid-task, then the coordinator SIGKILLed after 12 merges and
// restarted on the same port and data: the job ends with the local image, bit for bit.
// `static_tasks`: the plan's tasks before any localization.
void KilledWorkerAndCoordinatorRestart(const std::vector<std::string>& flags, uint64_t static_tasks) {
  TestDir dir;
  const Image reference = RenderLocallyToImage(dir, flags);
  const std::vector<std::string> coordinator_args = {"--lease-seconds", "2", "--max-attempts", "10"};
  auto [coordinator, port, address, job_id] = StartCoordinatorWithJob(dir, coordinator_args, flags);
  ASSERT_FALSE(job_id.empty());
  {
    FarmClient client(address, "");
    EXPECT_EQ(client.GetJob(job_id).tasks_total(), static_tasks)
        << "every level's detail tasks from the start";
  }

  // A victim, SIGKILLed while it holds a lease. Paced at 0.5 s a render task (below the 2 s lease):
  // unpaced it rendered the whole job's 5-pixel tasks between two polls of its log and was never
  // seen mid-task (a CI run failed so).
  std::unique_ptr<Process> victim = StartFaultyWorker(
      address, dir.path(), "victim", {{"PF_TEST_PAUSE_AT", "render"}, {"PF_TEST_PAUSE_SECONDS", "0.5"}});
  ASSERT_TRUE(WaitUntil([&] { return MidTask(victim->log()); }, 60)) << ReadFile(victim->log());
  victim->Signal(SIGKILL);
  victim->Wait(5);

  std::vector<fs::path> logs;
  // Paced at 0.1 s a task: the ~30 tasks left after the 12th merge take the two workers over a
  // second, however fast the machine renders them, so the crash comes before the job ends.
  std::vector<std::unique_ptr<Process>> workers = StartTwoPatientWorkers(address, dir.path(), &logs, 0.1);
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
  // Localization tasks were created (by the first or the restarted coordinator) beyond the
  // static ones.
  EXPECT_GT(st.tasks_total(), static_tasks);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

TEST(HierarchicalFarm, KilledWorkerAndCoordinatorRestartGiveTheLocalImage) {
  KilledWorkerAndCoordinatorRestart(HierarchicalFlags(40000), 40);
}

// The same with --hier-part indirect: its emission + direct light tasks (one per row band of 8:
// 5 more static tasks, leased first) and the separate per-pixel part in the checkpoint must
// survive the killed worker and the restart as the map-part levels do.
TEST(HierarchicalFarm, IndirectPartKilledWorkerAndCoordinatorRestartGiveTheLocalImage) {
  std::vector<std::string> flags = HierarchicalFlags(40000);
  flags.insert(flags.end(), {"--hier-part", "indirect", "--hier-direct-samples", "2"});
  KilledWorkerAndCoordinatorRestart(flags, 45);
}

// HierarchicalFlags with n0 = 8 (n_l = 8, 4, 2, 1: 40 + 20 + 10 + 5 static tasks), so that a
// level lasts long enough to be caught half merged, and its static tasks (the same PlanSpec the
// flags describe): the test needs each task's level to know where a level starts and ends.
std::vector<std::string> LongerLevelsFlags() {
  std::vector<std::string> flags = HierarchicalFlags(100000);
  *(std::find(flags.begin(), flags.end(), "--base-samples") + 1) = "8";
  return flags;
}
std::vector<TaskSpec> StaticTasksOfLongerLevels() {
  const PlanSpec plan{.kind = PlanKind::kHierarchical,
                      .samples_per_pixel = 1,
                      .tile_size = 8,
                      .levels = 3,
                      .dims = 2,
                      .base_samples = 8,
                      .min_samples = 1};
  return HierarchicalStaticTasks(plan, 33, 33, 11);
}

// Per level: how many of its static tasks `merged` holds, and how many it has.
std::vector<std::pair<size_t, size_t>> LevelProgress(const std::vector<TaskSpec>& tasks,
                                                     const std::set<uint64_t>& merged) {
  std::vector<std::pair<size_t, size_t>> levels;
  for (const TaskSpec& t : tasks) {
    if (levels.size() <= t.round) levels.resize(t.round + 1);
    ++levels[t.round].second;
    if (merged.count(t.task_id)) ++levels[t.round].first;
  }
  return levels;
}

// A level ≥ 1 with some of its tasks merged and at least `left` still to go ("mid-level"); -1 if none.
int LevelInProgress(const std::vector<std::pair<size_t, size_t>>& levels, size_t left) {
  for (size_t l = 1; l < levels.size(); ++l)
    if (levels[l].first > 0 && levels[l].first + left <= levels[l].second) return int(l);
  return -1;
}

// The hierarchical plan's farm check in one run: three workers, one SIGKILLed mid-task, then the coordinator
// SIGKILLed while a level ≥ 1 is partly merged and restarted on the same port and data; a
// replacement worker joins. The killed worker's task is re-run (after its lease expired, or after
// the restart), the restarted coordinator re-derives the level's state from its checkpoint and
// journal and creates the localization tasks once every level is complete, and the image is the
// local render's, bit for bit.
TEST(HierarchicalFarm, ThreeWorkersKilledWorkerAndRestartMidLevelGiveTheLocalImage) {
  TestDir dir;
  const std::vector<std::string> flags = LongerLevelsFlags();
  const Image reference = RenderLocallyToImage(dir, flags);
  const std::vector<TaskSpec> tasks = StaticTasksOfLongerLevels();
  ASSERT_EQ(tasks.size(), 75u);
  const std::vector<std::string> coordinator_args = {"--lease-seconds", "2", "--max-attempts", "10"};
  auto [coordinator, port, address, job_id] = StartCoordinatorWithJob(dir, coordinator_args, flags);
  ASSERT_FALSE(job_id.empty());

  std::vector<fs::path> logs;
  std::vector<std::unique_ptr<Process>> workers;
  // Paced at 0.05 s a task, so that a level ≥ 1 (20, 10 or 5 tasks) lasts long enough to be
  // caught half merged however fast the machine renders.
  for (const char* id : {"w1", "w2", "w3"}) {
    workers.push_back(StartFaultyWorker(address, dir.path(), id,
                                        {{"PF_TEST_PAUSE_AT", "render"}, {"PF_TEST_PAUSE_SECONDS", "0.05"}},
                                        {"--report-retry", "30"}));
    logs.push_back(dir / (std::string(id) + ".log"));
  }
  // w3 dies holding a lease.
  ASSERT_TRUE(WaitUntil([&] { return MidTask(logs[2]); }, 60)) << ReadFile(logs[2]);
  workers[2]->Signal(SIGKILL);
  workers[2]->Wait(5);

  // The coordinator dies while a level ≥ 1 is partly merged (at least 2 of its tasks to go).
  auto merged_ids = [&] {
    std::set<uint64_t> ids;
    for (const auto& [task, count] : MergedTaskCounts(logs, job_id)) ids.insert(task);
    return ids;
  };
  ASSERT_TRUE(WaitUntil([&] { return LevelInProgress(LevelProgress(tasks, merged_ids()), 2) >= 0; }, 120))
      << "no level was ever seen half merged";
  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  // What the dead coordinator had merged, from its own log: a level was in progress.
  std::set<uint64_t> merged_by_first;
  const std::regex merged_line("job " + job_id + " task ([0-9]+): merged");
  for (const std::string& line : ReadLines(coordinator->process().log())) {
    std::smatch m;
    if (std::regex_search(line, m, merged_line)) merged_by_first.insert(std::stoull(m[1].str()));
  }
  const auto levels = LevelProgress(tasks, merged_by_first);
  ASSERT_GE(LevelInProgress(levels, 1), 1) << "the coordinator was not killed in the middle of a level";

  coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), coordinator_args, port);
  EXPECT_FALSE(Grep(coordinator->process().log(), "resumed \\(RUNNING\\)").empty())
      << ReadFile(coordinator->process().log());
  workers.push_back(StartWorker(address, dir.path(), "w4", {"--report-retry", "30"}));

  FarmClient client(address, "");
  const v1::JobStatus st = WaitForJob(client, job_id, 180);
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_EQ(st.tasks_done(), st.tasks_total());
  EXPECT_GT(st.tasks_total(), 75u) << "localization tasks were created";
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  for (size_t i = 0; i < workers.size(); ++i) {
    if (i != 2) workers[i]->Signal(SIGTERM);
  }
  for (size_t i = 0; i < workers.size(); ++i) {
    if (i != 2) {
      EXPECT_TRUE(workers[i]->Wait(20).has_value());
    }
  }
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
  // --hier-part indirect splits the photon-map shader's radiance: refused for the path tracer
  // (by the coordinator; pf itself refuses the photon-map options, so they are left out).
  std::vector<std::string> path = Concat(base, {"--hier-part", "indirect"});
  *(std::find(path.begin(), path.end(), "--integrator") + 1) = "path";
  for (const char* option : {"--photons", "--k"}) {
    const auto it = std::find(path.begin(), path.end(), option);
    path.erase(it, it + 2);
  }
  const RunResult r = RunCommand(path, dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("spec.plan.hierarchical.part"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace pf::e2e
