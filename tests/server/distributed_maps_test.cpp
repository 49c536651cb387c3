// DistributedMaps (docs/farm.md, "Photon maps traced once") alone, with a fake clock: the piece queue that
// TraceChunk leases come from — oldest map first, a returned (undelivered) lease queued again at once without
// counting an attempt, expiry — without a scheduler, a gRPC server or a worker.
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
        maps_(
            DistributedMapsOptions{.dir = dir_.path() / "maps", .lease_seconds = 30, .chunk_photons = 16384},
            clock_, [this](const std::string& h) { return scenes_.DirectoryOf(h); }) {}

  // A job with one distributed map of `photons` (3 pieces of 16384 for 40000) over one tile.
  std::unique_ptr<Job> MakeJob(const std::string& id, uint64_t seq, uint64_t seed) {
    const JobConfig config = DistributedConfig(seed);
    TaskSpec task;
    task.map_index = 0;
    task.map_seed = MapSeed(seed, 0);
    return std::make_unique<Job>(id, seq, std::make_shared<const JobConfig>(config),
                                 std::vector<TaskSpec>{task}, 0);
  }

  // A job config with one distributed map of 40000 photons (MakeJob's), for a Scheduler.
  static JobConfig DistributedConfig(uint64_t seed) {
    JobConfig config = MakeConfig(MultipleMaps(1, 0), 16, 16);
    config.seed = seed;
    config.settings.integrator = IntegratorKind::kPhotonMap;
    config.settings.photons = 40000;
    config.settings.map_tracing = MapTracingMode::kDistributed;
    return config;
  }

  testing::TempDir dir_;
  FakeClock clock_;
  SqliteStore db_;
  SceneStore scenes_;
  DistributedMaps maps_;
};

TEST_F(DistributedMapsTest, PiecesOfTheOldestMapFirstAndAReturnedLeaseIsQueuedAgainAtOnce) {
  const std::unique_ptr<Job> a = MakeJob("job-a", 1, 11), b = MakeJob("job-b", 2, 12);
  EXPECT_FALSE(maps_.RenderTaskReady(*a, a->task(0))) << "the render task waits for its map";
  EXPECT_FALSE(maps_.RenderTaskReady(*b, b->task(0)));

  const std::optional<Lease> first = maps_.LeaseChunk({"w1", {}}, clock_.Now(), nullptr);
  ASSERT_TRUE(first && first->chunk);
  EXPECT_EQ(first->job_id, "job-a");
  EXPECT_EQ(first->chunk->chunk_index, 0u);
  EXPECT_EQ(first->chunk->chunk_count, 3u);
  EXPECT_EQ(first->attempt, 1u);

  // Undelivered (its long poll was cancelled): queued again now, not after the 30 s lease.
  maps_.Return(first->lease_id);
  EXPECT_EQ(maps_.counters().chunks_returned, 1u);
  EXPECT_FALSE(maps_.Extend(first->lease_id, "w1").ok) << "a returned lease is dead";
  maps_.Return(first->lease_id);  // twice, or an unknown lease: nothing happens
  maps_.Return("map-999");
  EXPECT_EQ(maps_.counters().chunks_returned, 1u);

  const std::optional<Lease> again = maps_.LeaseChunk({"w2", {}}, clock_.Now(), nullptr);
  ASSERT_TRUE(again && again->chunk);
  EXPECT_EQ(again->job_id, "job-a");
  EXPECT_EQ(again->chunk->chunk_index, 0u) << "the returned piece, at once";
  EXPECT_EQ(again->attempt, 1u) << "an undelivered lease is not an attempt";

  // The rest of job-a's map, then job-b's (oldest map first).
  std::vector<std::pair<std::string, uint32_t>> order;
  while (const std::optional<Lease> l = maps_.LeaseChunk({"w3", {}}, clock_.Now(), nullptr))
    order.emplace_back(l->job_id, l->chunk->chunk_index);
  const std::vector<std::pair<std::string, uint32_t>> expected = {
      {"job-a", 1}, {"job-a", 2}, {"job-b", 0}, {"job-b", 1}, {"job-b", 2}};
  EXPECT_EQ(order, expected);

  // Expiry: past the lease, every leased piece is queued again (attempt 2).
  clock_.Advance(31);
  maps_.Tick();
  EXPECT_EQ(maps_.counters().chunks_expired, 6u);
  const std::optional<Lease> retried = maps_.LeaseChunk({"w4", {}}, clock_.Now(), nullptr);
  ASSERT_TRUE(retried && retried->chunk);
  EXPECT_EQ(retried->job_id, "job-a");
  EXPECT_EQ(retried->chunk->chunk_index, 0u);
  EXPECT_EQ(retried->attempt, 2u);
}

// Piece leases: 128 CSPRNG bits, bound to their worker — another worker's ExtendLease, upload or
// FailTask changes nothing (its heartbeat does not keep the lease alive) — and a restarted
// coordinator never hands out an id again (ids were map-1, map-2, …, restarting at map-1, so an
// old worker's lease named a new piece).
TEST_F(DistributedMapsTest, PieceLeasesAreUnguessableBoundToTheirWorkerAndNotReusedAfterARestart) {
  const std::unique_ptr<Job> a = MakeJob("job-a", 1, 11);
  EXPECT_FALSE(maps_.RenderTaskReady(*a, a->task(0)));
  const std::optional<Lease> held = maps_.LeaseChunk({"holder", {}}, clock_.Now(), nullptr);
  ASSERT_TRUE(held && held->chunk);
  EXPECT_THAT(held->lease_id, ::testing::MatchesRegex("map-[0-9a-f]{32}"));
  std::set<std::string> before = {held->lease_id};
  while (const std::optional<Lease> l = maps_.LeaseChunk({"other", {}}, clock_.Now(), nullptr))
    before.insert(l->lease_id);
  EXPECT_EQ(before.size(), 3u);

  const ExtendResult stolen = maps_.Extend(held->lease_id, "thief");
  EXPECT_FALSE(stolen.ok);
  EXPECT_TRUE(stolen.not_holder);
  EXPECT_EQ(maps_.BeginUpload(held->lease_id, "thief"), DistributedMaps::UploadAdmission::kNotHolder);
  EXPECT_EQ(maps_.AcceptChunk(held->lease_id, "thief", "not even a piece"),
            DistributedMaps::Accepted::kNotHolder);
  EXPECT_EQ(maps_.Fail(held->lease_id, "thief", "sabotage"), FailOutcome::kNotHolder);
  EXPECT_TRUE(maps_.Extend(held->lease_id, "holder").ok);
  EXPECT_EQ(maps_.BeginUpload(held->lease_id, "holder"), DistributedMaps::UploadAdmission::kAdmitted);
  maps_.EndUpload(held->lease_id);
  // The thief's heartbeats do not keep the piece from being traced again once its holder is gone.
  clock_.Advance(20);
  EXPECT_FALSE(maps_.Extend(held->lease_id, "thief").ok);
  clock_.Advance(11);
  maps_.Tick();
  EXPECT_EQ(maps_.counters().chunks_expired, 3u);
  EXPECT_FALSE(maps_.Extend(held->lease_id, "holder").ok) << "ran out";

  // A restarted coordinator (same data directory) leases the same pieces under new ids only.
  DistributedMaps restarted(
      DistributedMapsOptions{.dir = dir_.path() / "maps", .lease_seconds = 30, .chunk_photons = 16384},
      clock_, [this](const std::string& h) { return scenes_.DirectoryOf(h); });
  const std::unique_ptr<Job> again = MakeJob("job-a", 1, 11);
  EXPECT_FALSE(restarted.RenderTaskReady(*again, again->task(0)));
  std::set<std::string> after;
  while (const std::optional<Lease> l = restarted.LeaseChunk({"holder", {}}, clock_.Now(), nullptr)) {
    EXPECT_EQ(before.count(l->lease_id), 0u) << l->lease_id << " was handed out before the restart";
    after.insert(l->lease_id);
  }
  EXPECT_EQ(after.size(), 3u);
  for (const std::string& old : before) {
    EXPECT_FALSE(restarted.Extend(old, "holder").ok);
    EXPECT_EQ(restarted.BeginUpload(old, "holder"), DistributedMaps::UploadAdmission::kNotLive);
  }
}

// Piece failures count against their worker in the map's job (worker_health.h): a worker that
// fails pieces 3 times is blocklisted — it is leased no more of the job's pieces — and the piece,
// failed on one worker only, is not given up: another worker traces it.
TEST_F(DistributedMapsTest, AWorkerFailingPiecesIsBlocklistedAndCannotUseAPieceUp) {
  Scheduler scheduler(clock_, SchedulerOptions{.lease_seconds = 30, .max_attempts = 3});
  maps_.SetScheduler(&scheduler);
  scheduler.SetMapTracingHook(&maps_);
  std::unique_ptr<Job> job = scheduler.PrepareJob(DistributedConfig(11));
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  const std::optional<Lease> healthy = scheduler.TryLease({"healthy", {}});
  ASSERT_TRUE(healthy && healthy->chunk);
  EXPECT_EQ(healthy->chunk->chunk_index, 0u);
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const std::optional<Lease> l = scheduler.TryLease({"flaky", {}});
    ASSERT_TRUE(l && l->chunk);
    EXPECT_EQ(l->chunk->chunk_index, 1u);
    EXPECT_EQ(l->attempt, attempt);
    EXPECT_EQ(maps_.Fail(l->lease_id, "flaky", "out of memory"), FailOutcome::kFailed);
  }
  EXPECT_EQ(maps_.counters().maps_left_to_workers, 0u) << "failed on one worker only";
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_QUEUED);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "flaky");
  EXPECT_FALSE(scheduler.TryLease({"flaky", {}}).has_value()) << "no more pieces of this job";
  const std::optional<Lease> retry = scheduler.TryLease({"healthy", {}});
  ASSERT_TRUE(retry && retry->chunk);
  EXPECT_EQ(retry->chunk->chunk_index, 1u);
  EXPECT_EQ(retry->attempt, 4u);
  int piece_events = 0;
  for (const v1::TaskEvent& e : scheduler.activity().Events(id)) piece_events += e.kind() == "piece-failed";
  EXPECT_EQ(piece_events, 3);
  scheduler.SetMapTracingHook(nullptr);
  maps_.SetScheduler(nullptr);
}

}  // namespace
}  // namespace pf::server
