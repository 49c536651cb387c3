// FarmActivity (server/scheduling/farm_activity.h): how refused workers are listed.
#include "server/scheduling/farm_activity.h"

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "server/clock.h"

namespace pf::server {
namespace {

namespace v1 = photonfarm::v1;

// The listed entry `id` (a copy), or nullopt.
std::optional<v1::WorkerInfo> Find(const std::vector<v1::WorkerInfo>& workers, const std::string& id) {
  for (const v1::WorkerInfo& w : workers)
    if (w.worker_id() == id) return w;
  return std::nullopt;
}

TEST(FarmActivity, ARefusedWorkerIsListedWithItsReasonAndCountUntilACallIsAccepted) {
  FakeClock clock;
  FarmActivity activity(clock);
  EXPECT_TRUE(activity.WorkerRefused("host-17", "UNAUTHENTICATED: authorization: invalid bearer token"));
  EXPECT_FALSE(activity.WorkerRefused("host-17", "UNAUTHENTICATED: authorization: invalid bearer token"));
  EXPECT_FALSE(activity.WorkerRefused("host-17", "UNAUTHENTICATED: authorization: invalid bearer token"));
  std::optional<v1::WorkerInfo> w = Find(activity.Workers(), "host-17");
  ASSERT_TRUE(w.has_value());
  EXPECT_TRUE(w->refused());
  EXPECT_EQ(w->refused_reason(), "UNAUTHENTICATED: authorization: invalid bearer token");
  EXPECT_EQ(w->refused_calls(), 3u);
  // Another reason is logged again (true) and counted afresh.
  EXPECT_TRUE(activity.WorkerRefused(
      "host-17", "PERMISSION_DENIED: authorization: WorkerService needs the worker credential"));
  EXPECT_EQ(Find(activity.Workers(), "host-17")->refused_calls(), 1u);
  // The token fixed: its next accepted call clears the refusal.
  activity.WorkerSeen("host-17", "ipv4:10.0.0.7:4242", 8, "v1");
  w = Find(activity.Workers(), "host-17");
  EXPECT_FALSE(w->refused());
  EXPECT_EQ(w->refused_reason(), "");
  EXPECT_EQ(w->refused_calls(), 0u);
}

TEST(FarmActivity, AnAnnouncedIdIsUntrustedAndCannotTakeOverALiveWorker) {
  FakeClock clock;
  FarmActivity activity(clock);
  activity.WorkerSeen("render-3", "ipv4:10.0.0.3:5000", 4, "v1");
  activity.WorkerRefused("render-3", "UNAUTHENTICATED: authorization: invalid bearer token");
  std::vector<v1::WorkerInfo> workers = activity.Workers();
  ASSERT_TRUE(Find(workers, "render-3").has_value());
  EXPECT_FALSE(Find(workers, "render-3")->refused()) << "the live worker's entry was taken over";
  ASSERT_TRUE(Find(workers, "render-3 (refused)").has_value());
  EXPECT_TRUE(Find(workers, "render-3 (refused)")->refused());
  // Also once the worker has been silent for long: the name stays the worker's.
  clock.Advance(3600);
  activity.WorkerRefused("render-3", "UNAUTHENTICATED: authorization: invalid bearer token");
  EXPECT_FALSE(Find(activity.Workers(), "render-3")->refused());
  EXPECT_EQ(Find(activity.Workers(), "render-3 (refused)")->refused_calls(), 2u);
  // No id, and ids that are long or not printable.
  activity.WorkerRefused("", "UNAUTHENTICATED: authorization: missing (expected 'Bearer <token>')");
  EXPECT_TRUE(Find(activity.Workers(), "(no worker id)").has_value());
  activity.WorkerRefused(std::string(500, 'x'), "UNAUTHENTICATED: authorization: invalid bearer token");
  EXPECT_TRUE(Find(activity.Workers(), std::string(64, 'x')).has_value());
  activity.WorkerRefused("bad\nid\x01", "UNAUTHENTICATED: authorization: invalid bearer token");
  EXPECT_TRUE(Find(activity.Workers(), "bad?id?").has_value());
}

TEST(FarmActivity, AFloodOfRefusedCallersNeverPushesAWorkerOut) {
  FakeClock clock;
  FarmActivity activity(clock);
  for (int i = 0; i < 50; ++i) activity.WorkerSeen("node-" + std::to_string(i), "ipv4:10.0.0.1:1", 2, "v1");
  for (int i = 0; i < 20000; ++i) {
    clock.Advance(0.001);
    activity.WorkerRefused("made-up-" + std::to_string(i),
                           "UNAUTHENTICATED: authorization: invalid bearer token");
  }
  const std::vector<v1::WorkerInfo> workers = activity.Workers();
  size_t refused = 0;
  for (const v1::WorkerInfo& w : workers) refused += w.refused();
  EXPECT_EQ(refused, kMaxRefusedKept);
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(Find(workers, "node-" + std::to_string(i)).has_value()) << i;
  EXPECT_TRUE(Find(workers, "made-up-19999").has_value()) << "the most recent refusal is kept";
  EXPECT_FALSE(Find(workers, "made-up-0").has_value());
}

}  // namespace
}  // namespace pf::server
