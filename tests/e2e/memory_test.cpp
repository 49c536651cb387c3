// Coordinator memory (docs/farm.md "Coordinator memory"): a job's accumulator —
// 47 bytes per pixel, ~787 MB for 4096² — is allocated when its first result arrives and freed
// once the finished job's image is in its checkpoint file, so queued and finished jobs cost
// O(tasks), not O(pixels). Measured on the real coordinator process (VmRSS).
#include <signal.h>

#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

// The documented bound (docs/farm.md): a coordinator with its jobs' task lists, SQLite, gRPC and
// thread stacks stays well below it; one 2048² accumulator (197 MB) alone exceeds it.
constexpr long kCoordinatorRssBoundMiB = 160;

long RssMiB(pid_t pid) {
  const long kib = MemoryOf(pid).rss_kib;
  return kib < 0 ? -1 : kib / 1024;
}

// A coordinator of its own per test, and path-traced jobs submitted to it with `pf submit`.
class CoordinatorMemory : public ::testing::Test {
 protected:
  static JobArgs PathJob() {
    JobArgs job;
    job.integrator = "path";
    return job;
  }
  RunResult Submit(const JobArgs& job) {
    return RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()), at),
                      dir.path());
  }

  TestDir dir;
  CoordinatorProcess coordinator{dir / "data", dir.path()};
  const std::vector<std::string> at = {"--coordinator", coordinator.address()};
};

TEST_F(CoordinatorMemory, TenQueued4096SquaredJobsStayUnderTheBound) {
  JobArgs job = PathJob();
  job.res = 4096;  // 16.7 Mpx: 787 MB per accumulator, 7.9 GB for ten if allocated at submit
  for (int i = 0; i < 10; ++i) {
    job.seed = uint64_t(i + 1);
    const RunResult r = Submit(job);
    ASSERT_EQ(r.exit_code, 0) << r.err;
  }
  const RunResult list = RunCommand(Concat({Binaries::Pf(), "list"}, at), dir.path());
  ASSERT_EQ(list.exit_code, 0) << list.err;
  const long rss = RssMiB(coordinator.process().pid());
  ASSERT_GT(rss, 0);
  EXPECT_LT(rss, kCoordinatorRssBoundMiB) << "coordinator RSS with 10 queued 4096² jobs: " << rss << " MiB";
}

// Recovery must not allocate either: a queued job resumed after a restart has nothing merged, so
// no image to hold (the recovery of a dynamic plan asked for the accumulator to derive created
// tasks and allocated 787 MB for this job).
TEST_F(CoordinatorMemory, AResumedQueuedJobDoesNotAllocateItsImage) {
  JobArgs job = PathJob();
  job.res = 4096;
  const RunResult r = Submit(job);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  coordinator.process().Signal(SIGKILL);
  ASSERT_TRUE(coordinator.process().Wait(20).has_value());
  CoordinatorProcess again(dir / "data", dir.path());
  const RunResult list = RunCommand({Binaries::Pf(), "list", "--coordinator", again.address()}, dir.path());
  ASSERT_EQ(list.exit_code, 0) << list.err;
  EXPECT_NE(list.out.find(r.out.substr(0, r.out.find('\n'))), std::string::npos) << "the job was resumed";
  const long rss = RssMiB(again.process().pid());
  ASSERT_GT(rss, 0);
  EXPECT_LT(rss, kCoordinatorRssBoundMiB)
      << "coordinator RSS after resuming a queued 4096² job: " << rss << " MiB";
}

// A job that ran to the end: its accumulator is freed once the final checkpoint is written, and
// its image is still served (read from the checkpoint).
TEST_F(CoordinatorMemory, FinishedJobFreesItsAccumulatorAndKeepsItsImage) {
  JobArgs job = PathJob();
  job.res = 2048;  // 197 MB accumulator: more than the bound by itself
  job.stride = 4;  // 16 tasks of 262k pixels (3 MB results)
  job.rounds = 1;
  RunResult r = Submit(job);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string id = r.out.substr(0, r.out.find('\n'));
  r = RunCommand({Binaries::FakeWorker(), "--coordinator", coordinator.address(), "--mode", "instant",
                  "--tasks", "16", "--seconds", "60", "--concurrency", "2"},
                 dir.path(), 90);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  r = RunCommand(Concat({Binaries::Pf(), "watch", id, "-q"}, at), dir.path(), 60);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  long rss = -1;
  EXPECT_TRUE(WaitUntil(
      [&] {
        rss = RssMiB(coordinator.process().pid());
        return rss >= 0 && rss < kCoordinatorRssBoundMiB;
      },
      30))
      << "coordinator RSS after the 2048² job finished: " << rss << " MiB";
  r = RunCommand(Concat({Binaries::Pf(), "get", id, "-o", (dir / "done.exr").string()}, at), dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const Image image = ReadImage(dir / "done.exr");
  EXPECT_EQ(image.width(), 2048);
  EXPECT_EQ(image.height(), 2048);
}

}  // namespace
}  // namespace pf::e2e
