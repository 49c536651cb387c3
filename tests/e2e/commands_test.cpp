// The `pf` farm commands against a real coordinator: submit prints only the job id, list shows
// it, cancel ends it (the merged image stays retrievable), watch and get on a finished job.
#include <nlohmann/json.hpp>

#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

TEST(FarmCommands, SubmitListCancelWatchGet) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::vector<std::string> at = {"--coordinator", coordinator.address()};
  RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, JobArgs().ToFlags()),
                                  Concat(at, {"--name", "to-cancel", "--priority", "5"})),
                           dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  EXPECT_EQ(r.out, id + "\n") << "stdout carries the job id only";

  r = RunCommand(Concat({Binaries::Pf(), "list", "--json"}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  nlohmann::json jobs = nlohmann::json::parse(r.out);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0]["job_id"], id);
  EXPECT_EQ(jobs[0]["state"], "queued");
  EXPECT_EQ(jobs[0]["name"], "to-cancel");
  EXPECT_EQ(jobs[0]["priority"], 5);

  r = RunCommand(Concat({Binaries::Pf(), "cancel", id}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("cancelled"), std::string::npos) << r.out;
  r = RunCommand(Concat({Binaries::Pf(), "list"}, at), dir.path());  // unfinished only: empty
  EXPECT_EQ(r.out.find(id), std::string::npos) << r.out;
  r = RunCommand(Concat({Binaries::Pf(), "list", "--all"}, at), dir.path());
  EXPECT_NE(r.out.find("cancelled"), std::string::npos) << r.out;

  // watch on a cancelled job: returns at once, exit 1; get still works.
  r = RunCommand(Concat({Binaries::Pf(), "watch", id, "-q"}, at), dir.path(), 30);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.out.find("cancelled"), std::string::npos) << r.out;
  r = RunCommand(Concat({Binaries::Pf(), "get", id, "-o", (dir / "cancelled.exr").string()}, at), dir.path());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(ReadImage(dir / "cancelled.exr").width(), 32);

  // No coordinator there: exit 1 with UNAVAILABLE, within the deadline.
  r = RunCommand({Binaries::Pf(), "list", "--coordinator", "127.0.0.1:1", "--timeout", "2"}, dir.path(), 30);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("UNAVAILABLE"), std::string::npos) << r.err;
}

// `pf submit` without --plan: the coordinator chooses (--plan auto, docs/farm.md "Choosing the
// plan"), stores the choice in the job and reports it; --photons is the budget over all maps.
TEST(FarmCommands, SubmitWithoutAPlanRunsTheAutoPlanAndReportsIt) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::vector<std::string> at = {"--coordinator", coordinator.address()};
  auto worker = StartWorker(coordinator.address(), dir.path(), "w1");
  // The Cornell box is diffuse only (no caustic map): skipping, 4x4 maps of 40000 / 16 photons.
  const std::vector<std::string> job = {"--integrator", "photonmap", "--photons", "40000", "--k",    "20",
                                        "--spp",        "2",         "--res",     "32x32", "--seed", "3"};
  RunResult r =
      RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job), at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));

  r = RunCommand(Concat({Binaries::Pf(), "watch", id, "-q"}, at), dir.path(), 120);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("succeeded"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("plan skipping"), std::string::npos) << r.out;
  EXPECT_NE(
      r.out.find("(auto: no caustic map: skipping S 2 x 1 rounds = 4 maps of 10000 photons (budget 40000)"),
      std::string::npos)
      << r.out;

  r = RunCommand(Concat({Binaries::Pf(), "list", "--all", "--json"}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const nlohmann::json jobs = nlohmann::json::parse(r.out);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0]["state"], "succeeded");
  EXPECT_EQ(jobs[0]["tasks_done"], 4);
  EXPECT_EQ(jobs[0]["samples_merged"], 32 * 32 * 2);
  EXPECT_NE(jobs[0]["plan"].get<std::string>().find("skipping"), std::string::npos) << jobs[0]["plan"];
  EXPECT_NE(jobs[0]["plan_auto_reason"].get<std::string>().find("1 workers"), std::string::npos)
      << jobs[0]["plan_auto_reason"];

  // Plan-shape flags with auto: exit 3 naming the flag, nothing submitted.
  r = RunCommand(
      Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene(), "--plan", "auto", "--maps", "3"}, job), at),
      dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("--maps: not used by --plan auto"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace pf::e2e
