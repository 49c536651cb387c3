// Bounded resources (docs/security.md "Budgets", docs/farm.md "Coordinator memory"):
//   - a finished job keeps its counts, not its task list, in memory and in SQLite, also after a
//     restart;
//   - the per-client and global budgets refuse a request before its work, RESOURCE_EXHAUSTED
//     naming the field and the budget;
//   - a WatchJob stream whose client does not read is ended after watch_unread_seconds.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "common/scene/scene_bundle.h"
#include "proto/convert.h"
#include "server/rpc/budgets.h"
#include "server/rpc/job_images.h"
#include "server/rpc/watch_hub.h"
#include "server/scheduling/recovery.h"
#include "server/store/persister.h"
#include "server/store/scene_store.h"
#include "tests/server/server_test_util.h"
#include "tests/util/job_specs.h"
#include "tests/util/raw_connection.h"
#include "tests/util/raw_http2.h"

namespace pf::server {
namespace {
using testing::Ctx;
using ::testing::HasSubstr;
using testing::LiveCoordinator;
using testing::MakeConfig;
using testing::MultipleMaps;
using testing::TempDir;
namespace v1 = photonfarm::v1;
namespace fs = std::filesystem;

// Polls `predicate` every 20 ms until it holds or `seconds` pass.
bool WaitFor(const std::function<bool()>& predicate, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (!predicate()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

// A job as SubmitJob stores it: its row, no task rows.
std::string SubmitAsTheServiceDoes(Scheduler& scheduler, SqliteStore& db, JobConfig config) {
  std::unique_ptr<Job> job = scheduler.PrepareJob(std::move(config));
  db.InsertJob({job->id(), job->seq(), job->config().spec.SerializeAsString(), JobState::kQueued, "",
                job->submitted_unix_ms(), 0},
               {});
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  return id;
}

// 32 maps of one-pixel tiles of a 12×10 image: 3840 tasks.
JobConfig ManyTasks(const SceneCatalog& catalog) {
  v1::JobSpec spec = testing::SkippingSpec(1, 1);
  spec.mutable_plan()->mutable_multiple_maps()->set_maps(32);
  spec.mutable_plan()->mutable_multiple_maps()->set_tile_size(1);
  spec.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
  return ValidateJobSpec(spec, catalog);
}

// Before, a cancelled job kept every task's spec and runtime (~400 bytes each) for good, and its
// cancellation wrote one row per task; after a restart all of them were expanded again.
TEST(FinishedJobs, ACancelledJobKeepsCountsNotTasksAndWritesNoRowPerTask) {
  TempDir dir;
  FakeClock clock;
  testing::FakeCatalog catalog;
  const fs::path db_file = dir.path() / "coordinator.db", cp_dir = dir.path() / "checkpoints";
  std::string id;
  v1::JobStatus before;
  {
    SqliteStore db(db_file);
    Scheduler scheduler(clock, SchedulerOptions{});
    Persister persister(scheduler, db, cp_dir, clock, /*interval=*/0);
    id = SubmitAsTheServiceDoes(scheduler, db, ManyTasks(catalog));
    const Lease merged = *scheduler.TryLease({"w", {}});
    ASSERT_EQ(
        scheduler.Complete(merged.lease_id, merged.worker_id, testing::SyntheticResult(merged.task, 12, 10))
            .status,
        CompleteStatus::kMerged);
    ASSERT_TRUE(scheduler.TryLease({"w", {}}).has_value());  // leased when the job is cancelled
    persister.FlushNow(true);
    EXPECT_EQ(scheduler.counters().tasks_in_memory, 3840u);
    scheduler.Cancel(id);
    // The cancellation's rows, then (next flush: every row stored) the release.
    persister.FlushNow(false);
    persister.FlushNow(false);
    EXPECT_EQ(scheduler.counters().tasks_in_memory, 0u) << "the cancelled job still holds its task list";
    before = scheduler.Status(id);
    EXPECT_EQ(before.state(), v1::JOB_STATE_CANCELLED);
    EXPECT_EQ(before.tasks_total(), 3840u);
    EXPECT_EQ(before.tasks_done(), 1u);
    EXPECT_EQ(before.tasks_cancelled(), 3839u);
    EXPECT_EQ(before.progress(), 1.0 / 3840);
    EXPECT_LE(db.LoadTasks(id).size(), 2u) << "a row for each task the job's end cancelled";
    EXPECT_EQ(EncodeJobImage(scheduler, id).status.tasks_done(), 1u)
        << "its image is served from the checkpoint";
    persister.Stop();
  }
  // After a restart: the same status, still no task list.
  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  const RecoveryReport report = RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_EQ(report.jobs_finished, 1u);
  EXPECT_EQ(scheduler.counters().tasks_in_memory, 0u) << "recovery expanded the finished job's plan";
  const v1::JobStatus after = scheduler.Status(id);
  EXPECT_EQ(after.state(), before.state());
  EXPECT_EQ(after.tasks_total(), before.tasks_total());
  EXPECT_EQ(after.tasks_done(), before.tasks_done());
  EXPECT_EQ(after.tasks_cancelled(), before.tasks_cancelled());
  EXPECT_EQ(after.tasks_queued() + after.tasks_running(), 0u);
  EXPECT_EQ(after.samples_merged(), before.samples_merged());
  EXPECT_EQ(after.progress(), before.progress());
  EXPECT_EQ(EncodeJobImage(scheduler, id).chunks.size(), 1u);
}

// Recovery counts a finished job's tasks without expanding its plan (ScheduledTaskCount); the
// count must be the expansion's for every plan.
TEST(FinishedJobs, TheScheduledTaskCountIsTheExpansionsForEveryPlan) {
  std::vector<std::pair<std::string, JobConfig>> configs = {
      {"multiple maps", MakeConfig(MultipleMaps(3, 8), 20, 12)},
      {"tail tiles", MakeConfig(PlanSpec{.kind = PlanKind::kMultipleMaps,
                                         .maps = 2,
                                         .samples_per_pixel = 2,
                                         .tile_size = 64,
                                         .tail_tile_size = 32},
                                100, 70)},
      {"maps in turn",
       MakeConfig(PlanSpec{.kind = PlanKind::kMapsInTurn, .samples_per_pixel = 3, .tile_size = 8}, 20, 12)},
      {"skipping", MakeConfig(testing::Skipping(3, 4), 20, 12)},
      {"skipping, max rounds", MakeConfig(testing::Skipping(3, 4), 20, 12, 0, StopRule{.max_rounds = 2})},
      {"hierarchical", MakeConfig(PlanSpec{.kind = PlanKind::kHierarchical,
                                           .tile_size = 32,
                                           .levels = 4,
                                           .dims = 2,
                                           .base_samples = 4,
                                           .min_samples = 1,
                                           .decay = 1.5},
                                  65, 40)},
  };
  for (const auto& [name, config] : configs)
    EXPECT_EQ(ScheduledTaskCount(config), ScheduledTasks(config).size()) << name;
}

TEST(Budgets, LimitFlagsAreParsedStrictly) {
  Budgets b;
  SetBudget(&b, "jobs_per_client=3");
  SetBudget(&b, "watch_unread_seconds=1.5");
  SetBudget(&b, "tasks_per_job=1048576");
  EXPECT_EQ(b.jobs_per_client, 3u);
  EXPECT_EQ(b.watch_unread_seconds, 1.5);
  EXPECT_THAT(DescribeBudgets(b), HasSubstr("jobs_per_client=3 jobs_total=4000"));
  for (const char* bad :
       {"jobs", "jobs=1", "jobs_per_client=0", "jobs_per_client=-1", "jobs_per_client=1e3",
        "jobs_per_client=", "tasks_per_job=1048577", "upload_bytes=67108865", "pixels_per_job=16777217",
        "watch_unread_seconds=0", "watch_unread_seconds=nan", "jobs_per_client=99999999999999999999"}) {
    try {
      SetBudget(&b, bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr("--limit")) << bad;
    }
  }
}

// An in-process coordinator with `budgets`, the Cornell box uploaded.
class BudgetTest : public ::testing::Test {
 protected:
  void Start(const Budgets& budgets) {
    live_.reset();
    CoordinatorOptions o = testing::CountingOptions(dir_.path() / ("data" + std::to_string(starts_++)));
    o.budgets = budgets;
    live_ = std::make_unique<LiveCoordinator>(o);
    hash_ = testing::UploadCornell(*live_);
  }
  // The Cornell box at width × height with `maps` maps of 8×8 tiles.
  grpc::Status Submit(uint32_t width, uint32_t height, uint32_t maps, std::string* id = nullptr) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = test_util::CornellPhotonMapSpec(hash_, width, height, 1, 3);
    req.mutable_spec()->mutable_plan()->mutable_multiple_maps()->set_maps(maps);
    req.mutable_spec()->mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
    req.mutable_spec()->mutable_plan()->mutable_multiple_maps()->set_tile_size(8);
    v1::SubmitJobResponse resp;
    const grpc::Status st = live_->render->SubmitJob(Ctx().get(), req, &resp);
    if (id) *id = resp.job_id();
    return st;
  }
  void Cancel(const std::string& id) {
    v1::CancelJobRequest req;
    req.set_job_id(id);
    v1::CancelJobResponse resp;
    ASSERT_TRUE(live_->render->CancelJob(Ctx().get(), req, &resp).ok());
  }
  static void ExpectRefused(const grpc::Status& st, const std::string& field, const std::string& budget) {
    EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
    EXPECT_EQ(st.error_message().rfind(field + ":", 0), 0u) << st.error_message();
    EXPECT_THAT(st.error_message(), HasSubstr("the budget " + budget + " = "));
    EXPECT_THAT(st.error_message(), HasSubstr("--limit " + budget + "=N"));
  }

  TempDir dir_;
  int starts_ = 0;
  std::unique_ptr<LiveCoordinator> live_;
  std::string hash_;
};

TEST_F(BudgetTest, JobsOverAPerJobBudgetAreRefusedNamingItsField) {
  Budgets b;
  b.tasks_per_job = 20;
  b.pixels_per_job = 32 * 32;
  Start(b);
  EXPECT_TRUE(Submit(32, 32, 1).ok());                                             // 16 tasks of 1024 pixels
  ExpectRefused(Submit(32, 32, 2), "spec.plan", "tasks_per_job");                  // 32 tasks
  ExpectRefused(Submit(40, 32, 1), "spec.camera.width/height", "pixels_per_job");  // 20 tasks, 1280 pixels
}

// SubmitJob writes the job's row, not one row per task (56 MB for 2^20 tasks): a task without a row
// is QUEUED, which recovery assumes.
TEST_F(BudgetTest, SubmitJobWritesTheJobRowAndNoTaskRows) {
  Start(Budgets());
  std::string id;
  ASSERT_TRUE(Submit(32, 32, 4, &id).ok());
  SqliteStore db(dir_.path() / "data0" / "coordinator.db");
  EXPECT_EQ(db.LoadJobs().size(), 1u);
  EXPECT_EQ(db.LoadTasks(id).size(), 0u);
}

// Queued and running jobs count; finished ones do not (their tasks and pixels once released). One client here
// (every call comes from 127.0.0.1), so the per-client and the global budget are shown by two coordinators.
TEST_F(BudgetTest, QueuedAndRunningJobsCountAgainstTheirBudgetsUntilTheyEnd) {
  for (const char* budget : {"jobs_per_client", "jobs_total", "tasks_total", "pixels_total"}) {
    SCOPED_TRACE(budget);
    Budgets b;
    const std::string name = budget;
    if (name == "jobs_per_client") b.jobs_per_client = 2;
    if (name == "jobs_total") b.jobs_total = 2;
    if (name == "tasks_total") b.tasks_total = 32;  // two jobs of 16 tasks
    if (name == "pixels_total") b.pixels_total = 2 * 32 * 32;
    Start(b);
    std::string first;
    ASSERT_TRUE(Submit(32, 32, 1, &first).ok());
    ASSERT_TRUE(Submit(32, 32, 1).ok());
    const grpc::Status third = Submit(32, 32, 1);
    const std::string field = name.rfind("jobs", 0) == 0 ? "spec"
                              : name == "tasks_total"    ? "spec.plan"
                                                         : "spec.camera.width/height";
    ExpectRefused(third, field, name);
    if (name == "jobs_per_client") {
      EXPECT_THAT(third.error_message(), HasSubstr("client 'ipv4:127.0.0.1'"));
    }
    Cancel(first);
    // Its tasks and pixels count until they are released, at the persister's next flush.
    EXPECT_TRUE(WaitFor([&] { return Submit(32, 32, 1).ok(); }, 5)) << "a cancelled job still counts";
  }
}

TEST_F(BudgetTest, UploadsOverTheirBudgetsAreRefusedBeforeTheSceneIsLoaded) {
  const SceneBundle cornell = CollectBundle(testing::CornellManifest());
  Budgets b;
  b.scene_bytes_total = cornell.TotalBytes();
  Start(b);  // uploads the Cornell box: exactly the budget
  v1::UploadSceneRequest again;
  *again.mutable_bundle() = testing::ToProto(cornell);
  v1::UploadSceneResponse resp;
  EXPECT_TRUE(live_->render->UploadScene(Ctx().get(), again, &resp).ok()) << "a stored bundle costs nothing";
  v1::UploadSceneRequest other = again;
  v1::SceneFile* extra = other.mutable_bundle()->add_files();
  extra->set_path("notes.txt");
  extra->set_content("one byte more than the budget");
  ExpectRefused(live_->render->UploadScene(Ctx().get(), other, &resp), "bundle.files", "scene_bytes_total");

  b = Budgets();
  b.upload_bytes = cornell.TotalBytes();
  Start(b);
  ExpectRefused(live_->render->UploadScene(Ctx().get(), other, &resp), "bundle.files", "upload_bytes");
}

// Uploads in flight: a reservation is held from the request's arrival to its answer.
TEST(Admission, UploadsInFlightArePerClientAndInAll) {
  TempDir dir;
  FakeClock clock;
  SqliteStore db(dir.path() / "coordinator.db");
  SceneStore scenes(dir.path() / "scenes", db, clock);
  Scheduler scheduler(clock, SchedulerOptions{});
  Budgets b;
  b.uploads_per_client = 1;
  b.uploads_total = 2;
  Admission admission(b, scheduler, scenes);
  // Why an upload of `client` was refused ("admitted" if it was not).
  auto refusal = [&](const std::string& client) {
    try {
      admission.AdmitUpload(client, 100);
      return std::string("admitted");
    } catch (const LimitError& e) {
      return std::string(e.what());
    }
  };
  Reservation a = admission.AdmitUpload("ipv4:10.0.0.1", 100);
  EXPECT_THAT(refusal("ipv4:10.0.0.1"), HasSubstr("the budget uploads_per_client = 1"))
      << "a second upload of the client";
  Reservation c = admission.AdmitUpload("ipv4:10.0.0.2", 100);
  EXPECT_THAT(refusal("ipv4:10.0.0.3"), HasSubstr("the budget uploads_total = 2")) << "a third upload in all";
  a.Release();
  EXPECT_NO_THROW(admission.AdmitUpload("ipv4:10.0.0.1", 100));
}

// A WatchJob call from a client that never reads: its window of 0 bytes lets the coordinator
// send the answer's headers, never an update.
class UnreadWatch {
 public:
  UnreadWatch(int port, const std::string& job_id) : connection_(port) {
    v1::WatchJobRequest req;
    req.set_job_id(job_id);
    req.set_include_images(true);
    sent_ = connection_.connected() &&
            connection_.Send(test_util::GrpcCallBytes("127.0.0.1:" + std::to_string(port),
                                                      "/photonfarm.v1.RenderService/WatchJob",
                                                      req.SerializeAsString(), /*stream_window=*/0));
  }
  bool sent() const { return sent_; }

 private:
  test_util::RawConnection connection_;
  bool sent_ = false;
};

// A watch that reads: OK if its first update arrives, else the status that ended it.
grpc::Status WatchOnce(LiveCoordinator& live, const std::string& job_id) {
  v1::WatchJobRequest req;
  req.set_job_id(job_id);
  auto ctx = Ctx("", 5);
  auto reader = live.render->WatchJob(ctx.get(), req);
  v1::JobUpdate update;
  if (reader->Read(&update)) {
    ctx->TryCancel();
    while (reader->Read(&update)) {
    }
    reader->Finish();
    return grpc::Status::OK;
  }
  return reader->Finish();
}

// Before, watches had no budget and a stream that was not read stayed open (holding its snapshot)
// for as long as the connection lived.
TEST_F(BudgetTest, WatchesHaveABudgetAndAnUnreadOneIsEnded) {
  Budgets b;
  b.watchers_per_client = 1;
  b.watch_unread_seconds = 1;
  Start(b);
  std::string id;
  ASSERT_TRUE(Submit(32, 32, 1, &id).ok());
  ASSERT_TRUE(WatchOnce(*live_, id).ok());
  ASSERT_TRUE(WaitFor([&] { return live_->coordinator->watches().sessions() == 0; }, 5));
  {
    // The connection stays open meanwhile (closed, it would end the call).
    UnreadWatch unread(live_->port, id);
    ASSERT_TRUE(unread.sent());
    ASSERT_TRUE(WaitFor([&] { return live_->coordinator->watches().sessions() == 1; }, 5));
    ExpectRefused(WatchOnce(*live_, id), "WatchJob", "watchers_per_client");
    const auto start = std::chrono::steady_clock::now();
    ASSERT_TRUE(WaitFor([&] { return live_->coordinator->watches().sessions() == 0; }, 10))
        << "the unread watch was never ended";
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3));
    EXPECT_TRUE(WatchOnce(*live_, id).ok()) << "its place in the budget is free again";
  }  // a client that answers no PING holds a graceful shutdown for its grace period

  b = Budgets();
  b.watchers_total = 1;
  b.watch_unread_seconds = 30;
  Start(b);
  ASSERT_TRUE(Submit(32, 32, 1, &id).ok());
  UnreadWatch held(live_->port, id);
  ASSERT_TRUE(WaitFor([&] { return live_->coordinator->watches().sessions() == 1; }, 5));
  ExpectRefused(WatchOnce(*live_, id), "WatchJob", "watchers_total");
}

}  // namespace
}  // namespace pf::server
