// DistributedMaps (issue #12) alone, with a fake clock: the piece queue that TraceChunk leases
// come from — oldest map first, a returned (undelivered) lease queued again at once without
// counting an attempt, expiry — without a scheduler, a gRPC server or a worker.
#include "server/scheduling/distributed_maps.h"

#include <gtest/gtest.h>

#include <memory>

#include "server/jobs/job.h"
#include "server/store/scene_store.h"
#include "server/store/sqlite_store.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {

using testing::MakeConfig;
using testing::MultipleMaps;

class DistributedMapsTest : public ::testing::Test {
 protected:
  DistributedMapsTest()
      : db_(dir_.path() / "farm.sqlite"),
        scenes_(dir_.path() / "scenes", db_, clock_),
        maps_(
            DistributedMapsOptions{.dir = dir_.path() / "maps", .lease_seconds = 30, .chunk_photons = 16384},
            clock_, scenes_) {}

  // A job with one distributed map of `photons` (3 pieces of 16384 for 40000) over one tile.
  std::unique_ptr<Job> MakeJob(const std::string& id, uint64_t seq, uint64_t seed) {
    JobConfig config = MakeConfig(MultipleMaps(1, 0), 16, 16);
    config.seed = seed;
    config.settings.integrator = IntegratorKind::kPhotonMap;
    config.settings.photons = 40000;
    config.settings.map_tracing = MapTracingMode::kDistributed;
    TaskSpec task;
    task.map_index = 0;
    task.map_seed = MapSeed(seed, 0);
    return std::make_unique<Job>(id, seq, std::make_shared<const JobConfig>(config),
                                 std::vector<TaskSpec>{task}, 0);
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

}  // namespace
}  // namespace pf::server
