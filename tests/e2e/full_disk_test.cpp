// A full disk with real processes (docs/farm.md, "Durability"): the coordinator's data directory
// on a small tmpfs, filled up in the middle of a job while two real workers render it.
//  - While the disk is full no result is acknowledged (the workers log merged=false), the job
//    pauses and says why, and the coordinator keeps answering.
//  - kill -9 while it is full, space freed, restart: the job resumes; no task a worker saw
//    acknowledged is run again, and the image is bit-identical to the local render.
//  - SIGTERM while it is full: the final flush cannot store everything, so pf-coordinator exits 1.
// Mounting a file system needs root (CI runs as root); elsewhere the test says why it cannot run.
#include <signal.h>
#include <sys/mount.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <regex>
#include <set>
#include <thread>

#include "client/farm_client.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// A tmpfs of `megabytes` at `dir` for the life of the object.
class SmallFileSystem {
 public:
  SmallFileSystem(const fs::path& dir, int megabytes) : dir_(dir) {
    fs::create_directories(dir);
    const std::string options = "size=" + std::to_string(megabytes) + "m,mode=0700";
    if (::mount("tmpfs", dir.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, options.c_str()) != 0)
      error_ = std::strerror(errno);
  }
  ~SmallFileSystem() {
    if (error_.empty()) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  const std::string& error() const { return error_; }

  // Writes a ballast file until the file system is full.
  void Fill() {
    std::ofstream out(dir_ / "ballast", std::ios::binary);
    const std::string block(64 * 1024, 'x');
    while (out.write(block.data(), std::streamsize(block.size()))) {
    }
  }
  void Free() { fs::remove(dir_ / "ballast"); }

 private:
  fs::path dir_;
  std::string error_;
};

JobArgs DiskJob() {
  JobArgs job;
  job.photons = 40000;
  job.k = 50;
  job.stride = 2;
  job.rounds = 6;  // 24 tasks, paced at ≥ 0.1 s each (StartTwoPatientWorkers)
  job.spp = 2;
  return job;
}

// Tasks whose completion a worker logged with merged=false after a failed (UNAVAILABLE) report.
size_t NotStoredReports(const std::vector<fs::path>& logs) {
  size_t n = 0;
  for (const fs::path& log : logs) n += Grep(log, "could not store it").size();
  return n;
}

class FullDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    if (::geteuid() != 0) GTEST_SKIP() << "needs root to mount a small tmpfs (CI runs as root)";
  }
};

TEST_F(FullDisk, NothingAcknowledgedIsLostAndTheImageIsRightAfterACrashOnAFullDisk) {
  TestDir dir;
  const JobArgs job = DiskJob();
  ASSERT_EQ(RenderLocally(dir, job.ToFlags()).exit_code, 0);
  const Image reference = ReadImage(dir / "local.exr");
  SmallFileSystem disk(dir / "data", 24);
  ASSERT_EQ(disk.error(), "");

  const std::vector<std::string> args = {"--lease-seconds", "3"};
  auto [coordinator, port, address, job_id] = StartCoordinatorWithJob(dir, args, job.ToFlags());
  ASSERT_FALSE(job_id.empty());
  std::vector<fs::path> logs;
  std::vector<std::unique_ptr<Process>> workers = StartTwoPatientWorkers(address, dir.path(), &logs, 0.1);
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, job_id) >= 4; }, 120));

  disk.Fill();
  FarmClient client(address, "");
  // The job pauses, says why, and results that could not be stored are not acknowledged.
  v1::JobStatus paused;
  ASSERT_TRUE(WaitUntil(
      [&] {
        paused = client.GetJob(job_id);
        return paused.paused_for_storage();
      },
      60))
      << paused.ShortDebugString() << ReadFile(coordinator->process().log());
  EXPECT_NE(paused.storage_error().find("No space left on device"), std::string::npos)
      << paused.storage_error();
  // The pause is visible before the worker whose report was refused has logged the answer.
  EXPECT_TRUE(WaitUntil([&] { return NotStoredReports(logs) >= 1; }, 30))
      << "a worker was answered 'not stored'";
  EXPECT_NE(paused.state(), v1::JOB_STATE_SUCCEEDED);
  const size_t merged_when_paused = MergedTaskTotal(logs, job_id);
  std::this_thread::sleep_for(std::chrono::seconds(1));
  EXPECT_EQ(MergedTaskTotal(logs, job_id), merged_when_paused) << "nothing acknowledged while full";
  EXPECT_GE(client.ListJobs(true).size(), 1u) << "the coordinator keeps answering";

  coordinator->process().Signal(SIGKILL);
  coordinator->process().Wait(5);
  const std::map<uint64_t, int> acknowledged = MergedTaskCounts(logs, job_id);
  const std::vector<size_t> offsets = LineCounts(logs);

  disk.Free();
  coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), args, port);
  const v1::JobStatus done = WaitForJob(client, job_id, 180);
  ASSERT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED) << done.ShortDebugString();
  EXPECT_EQ(done.storage_error(), "");
  EXPECT_TRUE(Grep(coordinator->process().log(), "DATA LOSS").empty())
      << ReadFile(coordinator->process().log());

  const std::set<uint64_t> leased_after = LeasedTasksSince(logs, offsets, job_id);
  for (const auto& [task, count] : acknowledged)
    EXPECT_FALSE(leased_after.count(task)) << "task " << task << " was acknowledged, then re-run";
  EXPECT_EQ(done.samples_merged(), uint64_t(job.res) * job.res * job.spp * job.rounds);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), reference));
  std::printf(
      "%zu tasks acknowledged before the disk filled; %zu answered 'not stored'; %zu leased after the "
      "restart\n",
      acknowledged.size(), NotStoredReports(logs), leased_after.size());
  for (auto& w : workers) w->Signal(SIGTERM);
  for (auto& w : workers) EXPECT_TRUE(w->Wait(20).has_value());
}

TEST_F(FullDisk, ASigtermWhoseFinalFlushCannotStoreEverythingExitsOne) {
  TestDir dir;
  SmallFileSystem disk(dir / "data", 24);
  ASSERT_EQ(disk.error(), "");
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--lease-seconds", "3"});
  const JobArgs job = DiskJob();
  const std::string job_id = SubmitJob(dir, coordinator.address(), job.ToFlags());
  std::vector<fs::path> logs;
  std::vector<std::unique_ptr<Process>> workers =
      StartTwoPatientWorkers(coordinator.address(), dir.path(), &logs, 0.1);
  ASSERT_TRUE(WaitUntil([&] { return MergedTaskTotal(logs, job_id) >= 2; }, 120));
  disk.Fill();
  FarmClient client(coordinator.address(), "");
  ASSERT_TRUE(WaitUntil([&] { return client.GetJob(job_id).paused_for_storage(); }, 60));
  coordinator.process().Signal(SIGTERM);
  const std::optional<int> rc = coordinator.process().Wait(30);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 1) << ReadFile(coordinator.process().log());
  EXPECT_FALSE(Grep(coordinator.process().log(), "final flush incomplete").empty());
  for (auto& w : workers) w->Signal(SIGKILL);
}

}  // namespace
}  // namespace pf::e2e
