// DistributedMaps (docs/farm.md, "Photon maps traced once") under a Scheduler, with a fake clock: the pieces
// in the Scheduler's one queue that TraceChunk leases come from — oldest map first, a returned (undelivered)
// lease queued again at once without counting an attempt, expiry, a map left to the workers leaving the
// queue — and the piece leases the Scheduler's one lease table holds (lease_table.h), without a gRPC server
// or a worker.
#include "server/scheduling/distributed_maps.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <set>

#include "server/jobs/job.h"
#include "server/scheduling/scheduler.h"
#include "server/store/scene_store.h"
#include "server/store/sqlite_store.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {

using testing::MakeConfig;
using testing::MultipleMaps;
namespace v1 = photonfarm::v1;

class DistributedMapsTest : public ::testing::Test {
 protected:
  DistributedMapsTest()
      : db_(dir_.path() / "farm.sqlite"),
        scenes_(dir_.path() / "scenes", db_, clock_),
        maps_(Options(), clock_, [this](const std::string& h) { return scenes_.DirectoryOf(h); }),
        scheduler_(clock_, SchedulerOptions{.lease_seconds = 30, .max_attempts = 3}) {
    maps_.SetScheduler(&scheduler_);
    scheduler_.SetMapTracingHook(&maps_);
  }
  ~DistributedMapsTest() override {
    scheduler_.SetMapTracingHook(nullptr);
    maps_.SetScheduler(nullptr);
  }

  DistributedMapsOptions Options() const { return {.dir = dir_.path() / "maps", .chunk_photons = 16384}; }

  // A job config with one distributed map of 40000 photons (3 pieces of 16384) over one tile.
  static JobConfig DistributedConfig(uint64_t seed) {
    JobConfig config = MakeConfig(MultipleMaps(1, 0), 16, 16);
    config.seed = seed;
    config.settings.integrator = IntegratorKind::kPhotonMap;
    config.settings.photons = 40000;
    config.settings.map_tracing = MapTracingMode::kDistributed;
    return config;
  }
  // Such a job added to `scheduler` (its render task waits for the map); its id.
  static std::string AddJob(Scheduler& scheduler, uint64_t seed) {
    std::unique_ptr<Job> job = scheduler.PrepareJob(DistributedConfig(seed));
    const std::string id = job->id();
    scheduler.AddJob(std::move(job));
    return id;
  }

  testing::TempDir dir_;
  FakeClock clock_;
  SqliteStore db_;
  SceneStore scenes_;
  DistributedMaps maps_;
  Scheduler scheduler_;
};

TEST_F(DistributedMapsTest, PiecesOfTheOldestMapFirstAndAReturnedLeaseIsQueuedAgainAtOnce) {
  const std::string a = AddJob(scheduler_, 11), b = AddJob(scheduler_, 12);

  const std::optional<Lease> first = scheduler_.TryLease({"w1", {}});
  ASSERT_TRUE(first && first->chunk);
  EXPECT_EQ(first->job_id, a);
  EXPECT_EQ(first->chunk->chunk_index, 0u);
  EXPECT_EQ(first->chunk->chunk_count, 3u);
  EXPECT_EQ(first->attempt, 1u);
  EXPECT_EQ(first->lease_seconds, 30);

  // Undelivered (its long poll was cancelled): queued again now, not after the 30 s lease.
  scheduler_.ReturnLease(first->lease_id);
  EXPECT_EQ(maps_.counters().chunks_returned, 1u);
  EXPECT_FALSE(scheduler_.Extend(first->lease_id, "w1", 0).ok) << "a returned lease is dead";
  scheduler_.ReturnLease(first->lease_id);  // twice, or an unknown lease: nothing happens
  scheduler_.ReturnLease(a + ".0.1.0123456789abcdef0123456789abcdef");
  EXPECT_EQ(maps_.counters().chunks_returned, 1u);

  const std::optional<Lease> again = scheduler_.TryLease({"w2", {}});
  ASSERT_TRUE(again && again->chunk);
  EXPECT_EQ(again->job_id, a);
  EXPECT_EQ(again->chunk->chunk_index, 0u) << "the returned piece, at once";
  EXPECT_EQ(again->attempt, 1u) << "an undelivered lease is not an attempt";

  // The rest of a's map, then b's (oldest map first); their render tasks wait for the maps.
  std::vector<std::pair<std::string, uint32_t>> order;
  while (const std::optional<Lease> l = scheduler_.TryLease({"w3", {}})) {
    ASSERT_TRUE(l->chunk);
    order.emplace_back(l->job_id, l->chunk->chunk_index);
  }
  const std::vector<std::pair<std::string, uint32_t>> expected = {{a, 1}, {a, 2}, {b, 0}, {b, 1}, {b, 2}};
  EXPECT_EQ(order, expected);

  // Expiry, on the Scheduler's one tick: past the lease, every leased piece is queued again (attempt 2).
  clock_.Advance(31);
  scheduler_.Tick();
  EXPECT_EQ(maps_.counters().chunks_expired, 6u);
  const std::optional<Lease> retried = scheduler_.TryLease({"w4", {}});
  ASSERT_TRUE(retried && retried->chunk);
  EXPECT_EQ(retried->job_id, a);
  EXPECT_EQ(retried->chunk->chunk_index, 0u);
  EXPECT_EQ(retried->attempt, 2u);
}

// Piece leases: the one form of every lease id (job, piece, attempt, 128 CSPRNG bits), bound to their
// worker — another worker's ExtendLease, upload or FailTask changes nothing (its heartbeat does not keep
// the lease alive) — and a restarted coordinator never hands out an id again (ids were map-1, map-2, …,
// restarting at map-1, so an old worker's lease named a new piece).
TEST_F(DistributedMapsTest, PieceLeasesAreUnguessableBoundToTheirWorkerAndNotReusedAfterARestart) {
  const std::string a = AddJob(scheduler_, 11);
  const std::optional<Lease> held = scheduler_.TryLease({"holder", {}});
  ASSERT_TRUE(held && held->chunk);
  EXPECT_THAT(held->lease_id, ::testing::MatchesRegex(a + "\\.0\\.1\\.[0-9a-f]{32}"));
  std::set<std::string> before = {held->lease_id};
  while (const std::optional<Lease> l = scheduler_.TryLease({"other", {}})) before.insert(l->lease_id);
  EXPECT_EQ(before.size(), 3u);

  const ExtendResult stolen = scheduler_.Extend(held->lease_id, "thief", 0);
  EXPECT_FALSE(stolen.ok);
  EXPECT_TRUE(stolen.not_holder);
  EXPECT_EQ(maps_.BeginUpload(held->lease_id, "thief"), DistributedMaps::UploadAdmission::kNotHolder);
  EXPECT_EQ(maps_.AcceptChunk(held->lease_id, "thief", "not even a piece"),
            DistributedMaps::Accepted::kNotHolder);
  EXPECT_EQ(scheduler_.Fail(held->lease_id, "thief", "sabotage", true), FailOutcome::kNotHolder);
  ASSERT_EQ(scheduler_.Status(a).blocklisted_workers_size(), 1) << "the presenter, in the map's job";
  EXPECT_EQ(scheduler_.Status(a).blocklisted_workers(0).worker_id(), "thief");
  EXPECT_TRUE(scheduler_.Extend(held->lease_id, "holder", 0).ok);
  EXPECT_EQ(maps_.BeginUpload(held->lease_id, "holder"), DistributedMaps::UploadAdmission::kAdmitted);
  EXPECT_EQ(maps_.BeginUpload(held->lease_id, "holder"), DistributedMaps::UploadAdmission::kBusy);
  maps_.EndUpload(held->lease_id);
  // The thief's heartbeats do not keep the piece from being traced again once its holder is gone.
  clock_.Advance(20);
  EXPECT_FALSE(scheduler_.Extend(held->lease_id, "thief", 0).ok);
  clock_.Advance(11);
  scheduler_.Tick();
  EXPECT_EQ(maps_.counters().chunks_expired, 3u);
  EXPECT_FALSE(scheduler_.Extend(held->lease_id, "holder", 0).ok) << "ran out";
  EXPECT_EQ(scheduler_.Fail(held->lease_id, "holder", "late", true), FailOutcome::kUnknownLease);

  // A restarted coordinator (same data directory) leases the same pieces under new ids only.
  DistributedMaps restarted(Options(), clock_,
                            [this](const std::string& h) { return scenes_.DirectoryOf(h); });
  Scheduler restarted_scheduler(clock_, SchedulerOptions{.lease_seconds = 30});
  restarted.SetScheduler(&restarted_scheduler);
  restarted_scheduler.SetMapTracingHook(&restarted);
  AddJob(restarted_scheduler, 11);
  std::set<std::string> after;
  while (const std::optional<Lease> l = restarted_scheduler.TryLease({"holder", {}})) {
    EXPECT_EQ(before.count(l->lease_id), 0u) << l->lease_id << " was handed out before the restart";
    after.insert(l->lease_id);
  }
  EXPECT_EQ(after.size(), 3u);
  for (const std::string& old : before) {
    EXPECT_FALSE(restarted_scheduler.Extend(old, "holder", 0).ok);
    EXPECT_EQ(restarted.BeginUpload(old, "holder"), DistributedMaps::UploadAdmission::kNotLive);
  }
  restarted_scheduler.SetMapTracingHook(nullptr);
  restarted.SetScheduler(nullptr);
}

// The one lease table dispatches by an entry's kind, not by the id's form: a piece's lease delivers no render
// result (CompleteTask ignores it and the piece stays leased), and a render task's lease uploads no piece.
TEST_F(DistributedMapsTest, TheLeaseTableDispatchesByKind) {
  JobConfig config = DistributedConfig(11);
  config.settings.map_tracing =
      MapTracingMode::kLocal;  // a job of render tasks only, leased after the pieces
  const std::string map_job = AddJob(scheduler_, 12);
  std::unique_ptr<Job> job = scheduler_.PrepareJob(config);
  scheduler_.AddJob(std::move(job));
  const std::optional<Lease> piece = scheduler_.TryLease({"w1", {}});
  ASSERT_TRUE(piece && piece->chunk);
  EXPECT_EQ(piece->job_id, map_job);
  const std::vector<float> pixels(16 * 16 * 3, 0.5f);
  EXPECT_EQ(scheduler_.Complete(piece->lease_id, "w1", pixels).status, CompleteStatus::kIgnored);
  EXPECT_TRUE(scheduler_.Extend(piece->lease_id, "w1", 0).ok) << "still the piece's live lease";
  bool rendered = false;
  while (const std::optional<Lease> l = scheduler_.TryLease({"w1", {}})) {
    if (l->chunk) continue;
    EXPECT_EQ(maps_.BeginUpload(l->lease_id, "w1"), DistributedMaps::UploadAdmission::kNotLive);
    EXPECT_TRUE(scheduler_.Extend(l->lease_id, "w1", 0).ok) << "the render task's lease is unchanged";
    rendered = true;
    break;
  }
  EXPECT_TRUE(rendered);
}

// Piece failures count against their worker in the map's job (worker_health.h): a worker that
// fails pieces 3 times is blocklisted — it is leased no more of the job's pieces, but those of
// another job's map — and the piece, failed on one worker only, is not given up: another worker
// traces it (lowest piece of the oldest map first).
TEST_F(DistributedMapsTest, AWorkerFailingPiecesIsBlocklistedAndCannotUseAPieceUp) {
  Scheduler& scheduler = scheduler_;
  const std::string id = AddJob(scheduler, 11);
  const std::optional<Lease> healthy = scheduler.TryLease({"healthy", {}});
  ASSERT_TRUE(healthy && healthy->chunk);
  EXPECT_EQ(healthy->chunk->chunk_index, 0u);
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const std::optional<Lease> l = scheduler.TryLease({"flaky", {}});
    ASSERT_TRUE(l && l->chunk);
    EXPECT_EQ(l->chunk->chunk_index, 1u);
    EXPECT_EQ(l->attempt, attempt);
    EXPECT_EQ(scheduler.Fail(l->lease_id, "flaky", "out of memory", true), FailOutcome::kFailed);
  }
  EXPECT_EQ(maps_.counters().maps_left_to_workers, 0u) << "failed on one worker only";
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_QUEUED);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "flaky");
  EXPECT_FALSE(scheduler.TryLease({"flaky", {}}).has_value()) << "no more pieces of this job";
  // The queue passes it over the older map, not over every map: a later job's pieces are its.
  const std::string later = AddJob(scheduler, 12);
  const std::optional<Lease> other = scheduler.TryLease({"flaky", {}});
  ASSERT_TRUE(other && other->chunk);
  EXPECT_EQ(other->job_id, later);
  EXPECT_EQ(other->chunk->chunk_index, 0u);
  const std::optional<Lease> retry = scheduler.TryLease({"healthy", {}});
  ASSERT_TRUE(retry && retry->chunk);
  EXPECT_EQ(retry->chunk->chunk_index, 1u);
  EXPECT_EQ(retry->attempt, 4u);
  int piece_events = 0;
  for (const v1::TaskEvent& e : scheduler.activity().Events(id)) piece_events += e.kind() == "piece-failed";
  EXPECT_EQ(piece_events, 3);
}

// A piece failed on max_attempts distinct workers leaves its map to the workers: the map's queued
// pieces leave the Scheduler's queue in the same hold of its lock, and its render task is queued.
TEST_F(DistributedMapsTest, AMapLeftToTheWorkersLeavesTheQueueAndReleasesItsRenderTasks) {
  const std::string id = AddJob(scheduler_, 11);
  for (const char* worker : {"w1", "w2", "w3"}) {
    const std::optional<Lease> l = scheduler_.TryLease({worker, {}});
    ASSERT_TRUE(l && l->chunk);
    EXPECT_EQ(l->chunk->chunk_index, 0u) << "the failed piece is queued again, lowest first";
    EXPECT_EQ(scheduler_.Fail(l->lease_id, worker, "out of memory", true), FailOutcome::kFailed);
  }
  EXPECT_EQ(maps_.counters().maps_left_to_workers, 1u);
  EXPECT_EQ(maps_.counters().chunks_leased, 3u);
  const std::optional<Lease> task = scheduler_.TryLease({"w4", {}});
  ASSERT_TRUE(task.has_value());
  EXPECT_FALSE(task->chunk.has_value()) << "pieces 1 and 2 left the queue with their map";
  EXPECT_EQ(task->job_id, id);
  EXPECT_FALSE(maps_.MapFor(id, 0).has_value()) << "its worker traces the map";
  EXPECT_FALSE(scheduler_.TryLease({"w4", {}}).has_value());
  EXPECT_EQ(maps_.counters().chunks_leased, 3u);
}

}  // namespace
}  // namespace pf::server
