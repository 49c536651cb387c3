// Deleting a job (docs/farm.md "Deleting jobs"): the registry and the scheduler forget a finished
// job (a live one is refused, naming its state) while a result in flight for it stays harmless; the
// store forgets its rows and finish time; the stored maps only it used leave the map store while a
// remaining job's stay; through DeleteJob the job's files go and a restart does not bring it back.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cstdio>

#include <chrono>
#include <fstream>
#include <memory>
#include <thread>

#include "server/errors.h"
#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/map_store_files.h"
#include "server/store/persister.h"
#include "server/store/sqlite_store.h"
#include "tests/server/server_test_util.h"
#include "tests/util/job_specs.h"

namespace pf::server {
namespace {
using testing::Ctx;
using ::testing::HasSubstr;
using testing::LiveCoordinator;
using testing::MakeConfig;
using testing::MultipleMaps;
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

TEST(JobRegistryRemove, ARemovedJobIsFoundNoMoreAndItsHolderKeepsIt) {
  JobRegistry jobs;
  auto [seq, id] = jobs.Allocate();
  auto config = std::make_shared<const JobConfig>(MakeConfig(MultipleMaps(1, 0), 4, 4));
  jobs.Add(std::make_unique<Job>(id, seq, config, std::vector<TaskSpec>{}, 0));
  const std::shared_ptr<Job> held = jobs.Shared(id);
  const std::shared_ptr<Job> removed = jobs.Remove(id);
  EXPECT_EQ(removed.get(), held.get());
  EXPECT_EQ(held->id(), id) << "the holder's job is still valid";
  EXPECT_EQ(jobs.Find(id), nullptr);
  EXPECT_THROW(jobs.Resolve(id), NotFoundError);
  EXPECT_THROW(jobs.Resolve(id.substr(0, 10)), NotFoundError) << "nor by a prefix";
  EXPECT_TRUE(jobs.InSubmissionOrder().empty());
  EXPECT_THROW(jobs.Remove(id), NotFoundError);
  EXPECT_GT(jobs.Allocate().first, seq) << "its seq is never handed out again";
}

class DeleteSchedulerTest : public testing::SchedulerFixture {};

TEST_F(DeleteSchedulerTest, OnlyAFinishedJobIsRemovedAndALateResultForItIsIgnored) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  const std::string other = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const std::optional<Lease> lease = scheduler_.TryLease({"w1", {}});
  ASSERT_TRUE(lease.has_value());
  ASSERT_EQ(lease->job_id, id);
  try {
    scheduler_.RemoveJob(id);
    ADD_FAILURE() << "removing a running job";
  } catch (const PreconditionError& e) {
    EXPECT_THAT(e.what(), HasSubstr("RUNNING"));
    EXPECT_THAT(e.what(), HasSubstr("cancel it first"));
  }
  EXPECT_THROW(scheduler_.CheckRemovable(other), PreconditionError) << "a queued job neither";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << "a refusal changes nothing";

  clock_.Advance(2.5);
  const v1::JobStatus cancelled = scheduler_.Cancel(id);
  EXPECT_EQ(cancelled.finished_unix_ms(), clock_.UnixMillis()) << "when it ended";
  EXPECT_EQ(scheduler_.Status(other).finished_unix_ms(), 0) << "a live job has not finished";
  EXPECT_EQ(scheduler_.CheckRemovable(id.substr(0, 12)), id) << "a prefix resolves";
  const std::shared_ptr<const JobConfig> config = scheduler_.RemoveJob(id.substr(0, 12));
  ASSERT_NE(config, nullptr);
  EXPECT_EQ(config->plan.maps, 2u);
  EXPECT_THROW(scheduler_.Status(id), NotFoundError);
  EXPECT_THROW(scheduler_.RemoveJob(id), NotFoundError);
  const std::vector<v1::JobStatus> all = scheduler_.List(/*include_finished=*/true);
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(all[0].job_id(), other);
  EXPECT_EQ(scheduler_.JobConfigs().size(), 1u);

  // The worker still rendering the deleted job's task hands its result in: ignored, no crash.
  const auto& cam = lease->config->camera;
  const CompleteResult late = scheduler_.Complete(
      lease->lease_id, lease->worker_id, testing::SyntheticResult(lease->task, cam.width, cam.height));
  EXPECT_EQ(late.status, CompleteStatus::kIgnored);
  // The farm goes on with the other job.
  const std::optional<Lease> next = scheduler_.TryLease({"w1", {}});
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->job_id, other);
  EXPECT_EQ(scheduler_.Load("").jobs, 1u);
}

TEST(SqliteStoreDelete, TheFinishTimeIsStoredAndADeletedJobHasNoRowsLeft) {
  testing::TempDir dir;
  const fs::path file = dir.path() / "coordinator.db";
  {
    SqliteStore db(file);
    db.InsertJob({"job-1", 1, "s1", JobState::kQueued, "", 42, 0}, {});
    db.InsertJob({"job-2", 2, "s2", JobState::kQueued, "", 43, 0}, {});
    JobRow done{"job-1", 1, "s1", JobState::kCancelled, "", 42, 1.5};
    done.finished_unix_ms = 123456789;
    db.Apply({done}, {});
    db.DeleteJob("job-2");
  }
  SqliteStore db(file);
  const std::vector<JobRow> rows = db.LoadJobs();
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].job_id, "job-1");
  EXPECT_EQ(rows[0].finished_unix_ms, 123456789);
}

// The database shrinks when jobs are deleted (incremental vacuuming, then a WAL checkpoint): 16 jobs
// of 2000 task rows, 15 deleted — the file holds one job's rows after, and no free pages. A database
// made without incremental vacuuming is converted when it is opened. The sizes are logged for
// docs/farm.md "Deleting jobs".
TEST(SqliteStoreDelete, TheDatabaseShrinksAfterDeletionsAndAnOldOneIsConverted) {
  testing::TempDir dir;
  const fs::path file = dir.path() / "coordinator.db";
  auto bytes = [&] {
    std::error_code ec;
    const fs::path wal = file.string() + "-wal";
    return fs::file_size(file) + (fs::exists(wal) ? fs::file_size(wal, ec) : 0);
  };
  auto pragma = [&](const char* name) {
    sqlite3* db = nullptr;
    EXPECT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    sqlite3_prepare_v2(db, (std::string("PRAGMA ") + name).c_str(), -1, &st, nullptr);
    const int64_t value = sqlite3_step(st) == SQLITE_ROW ? sqlite3_column_int64(st, 0) : -1;
    sqlite3_finalize(st);
    sqlite3_close(db);
    return value;
  };
  uint64_t full = 0, one_left = 0;
  {
    SqliteStore db(file);
    for (int j = 0; j < 16; ++j) {
      const std::string id = "job-" + std::to_string(j);
      db.InsertJob({id, uint64_t(j + 1), "s1", JobState::kQueued, "", 42, 0}, {});
      std::vector<TaskRow> tasks;
      for (uint64_t t = 0; t < 2000; ++t)
        tasks.push_back(
            {id, t, TaskState::kDone, 1, 0, "a last error of some length, as a failed attempt leaves"});
      db.Apply({}, tasks);
    }
    full = bytes();
    for (int j = 0; j < 15; ++j) db.DeleteJob("job-" + std::to_string(j));
    one_left = bytes();
    EXPECT_EQ(db.LoadTasks("job-15").size(), 2000u);
  }
  std::printf("coordinator.db with 16 jobs of 2000 task rows: %llu bytes; after 15 deleted: %llu bytes\n",
              (unsigned long long)full, (unsigned long long)one_left);
  EXPECT_LT(one_left * 5, full) << "the database did not shrink: " << full << " -> " << one_left;
  EXPECT_EQ(pragma("freelist_count"), 0);
  EXPECT_EQ(pragma("auto_vacuum"), 2);

  // A database from before: no auto-vacuum. Opened, it is converted, and deletions shrink it again.
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(file.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(sqlite3_exec(db, "PRAGMA auto_vacuum = NONE; VACUUM;", nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  }
  ASSERT_EQ(pragma("auto_vacuum"), 0);
  {
    SqliteStore db(file);
    EXPECT_EQ(db.LoadTasks("job-15").size(), 2000u) << "nothing lost by the conversion";
    const uint64_t before = bytes();
    db.DeleteJob("job-15");
    EXPECT_LT(bytes() * 5, before);
  }
  EXPECT_EQ(pragma("auto_vacuum"), 2);
  EXPECT_EQ(pragma("freelist_count"), 0);
}

// The map store: maps of the deleted job that a remaining job of the same scene, settings and seed
// reaches stay; the rest go, with their records; other jobs' maps are untouched.
TEST(RemoveMapsOf, OnlyTheMapsNoRemainingJobUsesGo) {
  testing::TempDir dir;
  FakeClock clock;
  const fs::path maps_dir = dir.path() / "maps";
  auto config = [](uint32_t maps, uint64_t seed) {
    JobConfig c = MakeConfig(MultipleMaps(maps, 0), 16, 16);
    c.seed = seed;
    c.settings.photons = 40000;
    c.settings.map_tracing = MapTracingMode::kDistributed;
    return c;
  };
  const JobConfig deleted = config(4, 5);
  const auto shares = std::make_shared<const JobConfig>(config(2, 5));  // maps 0 and 1 of the deleted job
  const auto elsewhere = std::make_shared<const JobConfig>(config(3, 6));
  fs::create_directories(maps_dir);
  auto write = [&](const fs::path& f) {
    std::ofstream(f) << "0123456789";
    std::ofstream(TracersFile(f)) << "w1\n";
  };
  std::vector<std::string> keys;
  for (uint64_t i = 0; i < 4; ++i) {
    keys.push_back(DistributedMapKey(deleted, MapSeed(5, i)));
    write(MapFileOf(maps_dir, keys.back()));
  }
  const std::string other_key = DistributedMapKey(*elsewhere, MapSeed(6, 0));
  write(MapFileOf(maps_dir, other_key));
  fs::create_directories(maps_dir / (keys[3] + ".chunks"));  // pieces of map 3 left from before
  std::ofstream(maps_dir / (keys[3] + ".chunks") / "0-16384") << "piece";

  DistributedMaps maps({.dir = maps_dir}, clock, [](const std::string&) { return fs::path(); });
  const DistributedMaps::Removed removed = maps.RemoveMapsOf("job-x", deleted, {shares, elsewhere});
  EXPECT_EQ(removed.maps, 2u);
  EXPECT_EQ(removed.bytes, 2 * (10 + 3) + 5u);
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir, keys[0])));
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir, keys[1])));
  EXPECT_FALSE(fs::exists(MapFileOf(maps_dir, keys[2])));
  EXPECT_FALSE(fs::exists(TracersFile(MapFileOf(maps_dir, keys[2]))));
  EXPECT_FALSE(fs::exists(MapFileOf(maps_dir, keys[3])));
  EXPECT_FALSE(fs::exists(maps_dir / (keys[3] + ".chunks")));
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir, other_key)));

  // With the sharing job gone too, its maps go when the deleted job's are removed again.
  EXPECT_EQ(maps.RemoveMapsOf("job-y", *shares, {elsewhere}).maps, 2u);
  EXPECT_FALSE(fs::exists(MapFileOf(maps_dir, keys[0])));
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir, other_key)));
}

class DeleteRpcTest : public testing::LiveCoordinatorTest {
 protected:
  std::string SubmitJob(uint64_t seed) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = test_util::CornellPhotonMapSpec(hash_, 32, 24, /*rounds=*/2, seed);
    v1::SubmitJobResponse resp;
    const grpc::Status st = live_->render->SubmitJob(Ctx().get(), req, &resp);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return resp.job_id();
  }
  grpc::Status Delete(const std::string& id, v1::DeleteJobResponse* out = nullptr) {
    v1::DeleteJobRequest req;
    req.set_job_id(id);
    v1::DeleteJobResponse resp;
    const grpc::Status st = live_->render->DeleteJob(Ctx().get(), req, &resp);
    if (out) *out = resp;
    return st;
  }
  grpc::Status Get(const std::string& id) {
    v1::GetJobRequest req;
    req.set_job_id(id);
    v1::JobStatus s;
    return live_->render->GetJob(Ctx().get(), req, &s);
  }
  void Cancel(const std::string& id) {
    v1::CancelJobRequest req;
    req.set_job_id(id);
    v1::CancelJobResponse resp;
    ASSERT_TRUE(live_->render->CancelJob(Ctx().get(), req, &resp).ok());
  }
};

TEST_F(DeleteRpcTest, ADeletedJobsFilesGoAndARestartDoesNotBringItBack) {
  const std::string gone = SubmitJob(3), kept = SubmitJob(4);
  grpc::Status st = Delete(gone);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(st.error_message(), HasSubstr("QUEUED"));
  st = Delete("");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(st.error_message(), HasSubstr("job_id"));
  EXPECT_EQ(Delete("job-notahexprefix").error_code(), grpc::StatusCode::NOT_FOUND);

  Cancel(gone);
  Cancel(kept);
  live_->coordinator->persister().FlushNow();
  // What recovery set aside of the job's files goes with it; another job's files stay.
  const fs::path checkpoints = dir_.path() / "data" / "checkpoints";
  std::ofstream(checkpoints / (gone + ".journal.damaged")) << "12345";
  std::ofstream(checkpoints / (kept + ".journal.damaged")) << "12345";
  v1::DeleteJobResponse resp;
  st = Delete(gone.substr(0, 10), &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(resp.job_id(), gone);
  EXPECT_EQ(resp.bytes_freed(), 5u);
  EXPECT_FALSE(fs::exists(checkpoints / (gone + ".journal.damaged")));
  EXPECT_TRUE(fs::exists(checkpoints / (kept + ".journal.damaged")));
  EXPECT_EQ(Get(gone).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(Delete(gone).error_code(), grpc::StatusCode::NOT_FOUND) << "deleted once";

  live_.reset();  // a restart on the same data directory
  live_ = std::make_unique<LiveCoordinator>(testing::CountingOptions(dir_.path() / "data"));
  EXPECT_EQ(Get(gone).error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_TRUE(Get(kept).ok());
  const RecoveryReport& recovered = live_->coordinator->recovery();
  EXPECT_EQ(recovered.jobs_resumed + recovered.jobs_finished + recovered.jobs_failed, 1u)
      << "only the kept job";
}

// pf-coordinator --retain-finished: a finished job goes once it ended longer ago than the retention,
// not before; a live job stays whatever its age.
TEST(Retention, AFinishedJobIsDeletedOnceItIsOlderThanTheRetention) {
  testing::TempDir dir;
  FakeClock clock;
  CoordinatorOptions options = testing::CountingOptions(dir.path() / "data");
  options.clock = &clock;
  options.retain_finished_seconds = 3600;
  LiveCoordinator live(options);
  const std::string hash = testing::UploadCornell(live);
  auto submit = [&](uint64_t seed) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = test_util::CornellPhotonMapSpec(hash, 32, 24, /*rounds=*/2, seed);
    v1::SubmitJobResponse resp;
    EXPECT_TRUE(live.render->SubmitJob(Ctx().get(), req, &resp).ok());
    return resp.job_id();
  };
  auto exists = [&](const std::string& id) {
    v1::GetJobRequest req;
    req.set_job_id(id);
    v1::JobStatus s;
    const grpc::Status st = live.render->GetJob(Ctx().get(), req, &s);
    EXPECT_TRUE(st.ok() || st.error_code() == grpc::StatusCode::NOT_FOUND) << st.error_message();
    return st.ok();
  };
  const std::string finished = submit(3), queued = submit(4);
  v1::CancelJobRequest cancel;
  cancel.set_job_id(finished);
  v1::CancelJobResponse cancelled;
  ASSERT_TRUE(live.render->CancelJob(Ctx().get(), cancel, &cancelled).ok());

  clock.Advance(1800);  // half the retention: checked (the check is due), kept
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_TRUE(exists(finished));
  clock.Advance(1800 + kRetentionCheckSeconds + 1);
  bool gone = false;
  for (int i = 0; i < 100 && !gone; ++i) {
    gone = !exists(finished);
    if (!gone) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_TRUE(gone) << "not deleted past the retention";
  EXPECT_TRUE(exists(queued)) << "a live job stays";
}

}  // namespace
}  // namespace pf::server
