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

}  // namespace
}  // namespace pf::e2e
