// `pf pause` / `pf resume` against a real coordinator and workers (docs/farm.md "Pausing a job"):
// a paused job starts no task while its leases in flight finish, resumes to the image of an
// unpaused run bit for bit, and stays paused across a coordinator restart. `pf delete` (docs/farm.md
// "Deleting jobs"): a finished job's files and the photon maps only it used leave the data
// directory, another job's stay retrievable, a restart does not bring it back, a live job is refused.
#include <signal.h>

#include <atomic>
#include <chrono>
#include <deque>
#include <filesystem>
#include <regex>
#include <set>
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

// The short keys (12 hex digits) of the maps the coordinator traced once for `job_id`.
std::set<std::string> MapKeysOf(const fs::path& coordinator_log, const std::string& job_id) {
  std::set<std::string> keys;
  const std::regex re("job " + job_id + " map [0-9]+: traced once, distributed .*key ([0-9a-f]{12})");
  for (const std::string& line : ReadLines(coordinator_log)) {
    std::smatch m;
    if (std::regex_search(line, m, re)) keys.insert(m[1].str());
  }
  return keys;
}

// Files of the maps directory whose name starts with one of `keys`.
size_t MapFilesOf(const fs::path& maps_dir, const std::set<std::string>& keys) {
  size_t n = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(maps_dir))
    n += keys.count(e.path().filename().string().substr(0, 12));
  return n;
}

size_t FilesStartingWith(const fs::path& dir, const std::string& prefix) {
  size_t n = 0;
  for (const fs::directory_entry& e : fs::directory_iterator(dir))
    n += e.path().filename().string().rfind(prefix, 0) == 0;
  return n;
}

TEST(JobLifecycle, ADeletedJobLeavesTheDataDirectoryAndStaysDeletedAcrossARestart) {
  TestDir dir;
  auto coordinator = std::make_unique<CoordinatorProcess>(dir / "data", dir.path());
  const std::string address = coordinator->address();
  const int port = coordinator->port();
  JobArgs a = LifecycleJob(), b = LifecycleJob();
  b.seed = a.seed + 1;  // other maps
  const std::vector<std::string> distributed = {"--map-tracing", "distributed"};
  const std::string id_a = SubmitJob(dir, address, Concat(a.ToFlags(), distributed));
  const std::string id_b = SubmitJob(dir, address, Concat(b.ToFlags(), distributed));
  ASSERT_FALSE(id_a.empty());
  ASSERT_FALSE(id_b.empty());
  {
    auto w1 = StartWorker(address, dir.path(), "w1");
    auto w2 = StartWorker(address, dir.path(), "w2");
    FarmClient client(address, "");
    ASSERT_EQ(WaitForJob(client, id_a, 90).state(), v1::JOB_STATE_SUCCEEDED);
    ASSERT_EQ(WaitForJob(client, id_b, 90).state(), v1::JOB_STATE_SUCCEEDED);
  }  // the workers stop: a job submitted from now on stays queued
  const fs::path checkpoints = dir / "data" / "checkpoints", maps = dir / "data" / "maps";
  const std::set<std::string> keys_a = MapKeysOf(coordinator->process().log(), id_a);
  const std::set<std::string> keys_b = MapKeysOf(coordinator->process().log(), id_b);
  ASSERT_EQ(keys_a.size(), 12u) << "one map per task of the skipping plan";
  ASSERT_EQ(keys_b.size(), 12u);
  // The final checkpoint of a finished job is written by the persister shortly after it ends.
  ASSERT_TRUE(WaitUntil([&] { return FilesStartingWith(checkpoints, id_a + ".acc") == 1; }, 10));
  ASSERT_EQ(MapFilesOf(maps, keys_a), 2 * keys_a.size()) << "each map and its .by record";
  const size_t files_b = MapFilesOf(maps, keys_b);
  ASSERT_EQ(files_b, 2 * keys_b.size());
  FarmClient client(address, "");
  const Image image_b = DecodeImage(client.GetImage(id_b));

  // Refused: a live job, an unknown id (exit 3), no id.
  JobArgs c = LifecycleJob();
  c.seed = a.seed + 2;  // not A's maps: a queued job of A's seed would keep them
  const std::string id_c = SubmitJob(dir, address, c.ToFlags());
  ASSERT_FALSE(id_c.empty());
  RunResult r = Pf(dir, address, {"delete", id_c});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("FAILED_PRECONDITION"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("cancel it first"), std::string::npos) << r.err;
  r = Pf(dir, address, {"delete", "job-notahexprefix"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
  EXPECT_EQ(client.GetJob(id_c).state(), v1::JOB_STATE_QUEUED) << "a refused delete changes nothing";

  // Deleted by a prefix of its id.
  r = Pf(dir, address, {"delete", id_a.substr(0, 12)});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("deleted " + id_a), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(12 photon maps)"), std::string::npos) << r.out;
  r = Pf(dir, address, {"list", "--all"});
  EXPECT_EQ(r.out.find(id_a), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(id_b), std::string::npos) << r.out;
  EXPECT_EQ(FilesStartingWith(checkpoints, id_a), 0u) << "its checkpoint and journal";
  EXPECT_EQ(MapFilesOf(maps, keys_a), 0u) << "the maps only it used";
  EXPECT_EQ(FilesStartingWith(checkpoints, id_b + ".acc"), 1u);
  EXPECT_EQ(MapFilesOf(maps, keys_b), files_b) << "the other job's maps stay";
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(id_b)), image_b));
  try {
    client.GetJob(id_a);
    ADD_FAILURE() << "GetJob of a deleted job";
  } catch (const RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::NOT_FOUND);
  }

  // A restart does not bring it back; the other job is still there, image and all.
  coordinator->process().Signal(SIGTERM);
  ASSERT_TRUE(coordinator->process().Wait(20).has_value());
  coordinator =
      std::make_unique<CoordinatorProcess>(dir / "data", dir.path(), std::vector<std::string>{}, port);
  r = Pf(dir, address, {"list", "--all"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.find(id_a), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(id_b), std::string::npos) << r.out;
  EXPECT_EQ(Pf(dir, address, {"get", id_a, "-o", (dir / "a.exr").string()}).exit_code, 3);
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(id_b)), image_b));
  EXPECT_TRUE(Grep(coordinator->process().log(), "orphaned").empty()) << "no file of it was left behind";
}

// pf purge --older-than: finished jobs older than that go (dry run first), younger and live ones stay.
TEST(JobLifecycle, PurgeDeletesTheJobsThatFinishedLongerAgo) {
  TestDir dir;
  CoordinatorProcess coordinator(dir / "data", dir.path());
  const std::string address = coordinator.address();
  const std::string old_id = SubmitJob(dir, address, LifecycleJob().ToFlags());
  ASSERT_FALSE(old_id.empty());
  FarmClient client(address, "");
  ASSERT_EQ(Pf(dir, address, {"cancel", old_id}).exit_code, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  const std::string young_id = SubmitJob(dir, address, LifecycleJob().ToFlags());
  ASSERT_EQ(Pf(dir, address, {"cancel", young_id}).exit_code, 0);
  const std::string live_id = SubmitJob(dir, address, LifecycleJob().ToFlags());

  RunResult r = Pf(dir, address, {"purge", "--older-than", "2s", "--dry-run"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("would delete " + old_id), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find(young_id), std::string::npos) << r.out;
  EXPECT_EQ(client.ListJobs(true).size(), 3u) << "a dry run deletes nothing";
  r = Pf(dir, address, {"purge", "--older-than", "2s"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("deleted " + old_id), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("purged 1 jobs"), std::string::npos) << r.out;
  std::set<std::string> left;
  for (const v1::JobStatus& s : client.ListJobs(true)) left.insert(s.job_id());
  EXPECT_EQ(left, (std::set<std::string>{young_id, live_id}));
  EXPECT_EQ(Pf(dir, address, {"purge", "--older-than", "soon"}).exit_code, 2) << "not a duration";
}

// The bytes of every regular file under `dir` (what --data-quota measures: server/store/data_quota.h,
// restated here so that the test does not take the coordinator's word for it). Its own recursion:
// a folder that vanishes while it walks must not end the count.
uint64_t BytesUnder(const fs::path& dir) {
  uint64_t total = 0;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code fec;
    const fs::file_status status = it->symlink_status(fec);
    if (fs::is_directory(status))
      total += BytesUnder(it->path());
    else if (fs::is_regular_file(status))
      total += it->file_size(fec) * !fec;
  }
  return total;
}

// --data-quota (docs/farm.md "The data dir's quota"): 200 jobs of 256x256 pixels, each leaving 3 MB
// of checkpoint (600 MB in all), through a coordinator with a 100 MB quota. Sampled every 20 ms
// and after every job, the data dir never holds more than the quota; every job succeeds (a job
// deleted while live would not); the jobs that ended last are kept, the ones that ended first go.
TEST(JobLifecycle, ADataDirUnderAQuotaStaysUnderItThrough200Jobs) {
  TestDir dir;
  constexpr uint64_t kQuota = uint64_t(100) << 20;
  constexpr int kJobs = 200;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--data-quota", "100M"});
  const std::string address = coordinator.address();
  std::vector<std::unique_ptr<Process>> workers;
  for (const char* id : {"q1", "q2"}) workers.push_back(StartWorker(address, dir.path(), id));
  std::atomic<bool> done{false};
  std::atomic<uint64_t> most{0};
  std::thread sampler([&] {
    while (!done) {
      const uint64_t bytes = BytesUnder(dir / "data");
      if (bytes > most) most = bytes;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  FarmClient client(address, "");
  std::vector<std::string> ids;
  std::deque<std::string> in_flight;
  int succeeded = 0;
  const auto finish_oldest = [&] {
    const v1::JobStatus st = WaitForJob(client, in_flight.front(), 120);
    EXPECT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << in_flight.front();
    succeeded += st.state() == v1::JOB_STATE_SUCCEEDED;
    in_flight.pop_front();
    EXPECT_LE(BytesUnder(dir / "data"), kQuota);
  };
  for (int i = 0; i < kJobs; ++i) {
    ids.push_back(SubmitJob(dir, address,
                            {"--integrator", "path", "--spp", "1", "--res", "256x256", "--plan",
                             "multiple-maps", "--seed", std::to_string(i + 1)}));
    ASSERT_FALSE(ids.back().empty());
    in_flight.push_back(ids.back());
    if (in_flight.size() >= 3) finish_oldest();
  }
  while (!in_flight.empty()) finish_oldest();
  done = true;
  sampler.join();
  EXPECT_EQ(succeeded, kJobs);
  EXPECT_LE(most.load(), kQuota) << "most bytes seen in the data dir";
  std::printf("most bytes seen in the data dir: %.1f MB of a %.0f MB quota\n", double(most) / (1 << 20),
              double(kQuota) / (1 << 20));
  // Without the quota the jobs would hold 600 MB: most of them were deleted, the first ones first.
  const std::vector<v1::JobStatus> left = client.ListJobs(true);
  EXPECT_LT(left.size(), 40u);
  EXPECT_GT(left.size(), 10u);
  std::set<std::string> kept;
  for (const v1::JobStatus& s : left) kept.insert(s.job_id());
  EXPECT_FALSE(kept.count(ids.front()));
  for (int i = kJobs - 5; i < kJobs; ++i)
    EXPECT_TRUE(kept.count(ids[i])) << "job " << i << " of the last five";
}

}  // namespace
}  // namespace pf::e2e
