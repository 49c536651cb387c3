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

// The refused entry of `address`, or nullopt.
std::optional<v1::WorkerInfo> RefusedAt(const std::vector<v1::WorkerInfo>& workers,
                                        const std::string& address) {
  for (const v1::WorkerInfo& w : workers)
    if (w.refused() && w.peer() == address) return w;
  return std::nullopt;
}

size_t CountRefused(const std::vector<v1::WorkerInfo>& workers) {
  size_t refused = 0;
  for (const v1::WorkerInfo& w : workers) refused += w.refused();
  return refused;
}

constexpr char kInvalid[] = "UNAUTHENTICATED: authorization: invalid bearer token";
constexpr char kDenied[] = "PERMISSION_DENIED: authorization: WorkerService needs the worker credential";

TEST(FarmActivity, RefusedCallsAreCountedPerAddressUntilTheCredentialWorks) {
  FakeClock clock;
  FarmActivity activity(clock);
  EXPECT_TRUE(activity.WorkerRefused("10.0.0.7", "host-17", kInvalid));
  EXPECT_FALSE(activity.WorkerRefused("10.0.0.7", "host-17", kInvalid));
  EXPECT_FALSE(activity.WorkerRefused("10.0.0.7", "host-17", kInvalid));
  std::optional<v1::WorkerInfo> w = RefusedAt(activity.Workers(), "10.0.0.7");
  ASSERT_TRUE(w.has_value());
  EXPECT_EQ(w->worker_id(), "host-17");
  EXPECT_EQ(w->refused_reason(), kInvalid);
  EXPECT_EQ(w->refused_calls(), 3u);
  // Another reason is logged again (true); the address's count goes on.
  EXPECT_TRUE(activity.WorkerRefused("10.0.0.7", "host-17", kDenied));
  ASSERT_TRUE(RefusedAt(activity.Workers(), "10.0.0.7").has_value());
  EXPECT_EQ(RefusedAt(activity.Workers(), "10.0.0.7")->refused_calls(), 4u);
  // A second worker on that host, and one on another: one entry per address.
  EXPECT_FALSE(activity.WorkerRefused("10.0.0.7", "host-17b", kDenied)) << "same address, same reason";
  EXPECT_TRUE(activity.WorkerRefused("10.0.0.8", "host-18", kInvalid));
  w = RefusedAt(activity.Workers(), "10.0.0.7");
  ASSERT_TRUE(w.has_value());
  ASSERT_TRUE(RefusedAt(activity.Workers(), "10.0.0.8").has_value());
  EXPECT_EQ(w->worker_id(), "host-17b, host-17");
  EXPECT_EQ(w->refused_calls(), 5u);
  EXPECT_EQ(RefusedAt(activity.Workers(), "10.0.0.8")->refused_calls(), 1u);
  // host-17's token fixed: its accepted call takes it off its address's entry (an accepted call
  // from elsewhere does not) ...
  activity.WorkerSeen("host-17", "ipv4:10.0.0.9:4242", 8, "v1");
  ASSERT_TRUE(RefusedAt(activity.Workers(), "10.0.0.7").has_value());
  EXPECT_EQ(RefusedAt(activity.Workers(), "10.0.0.7")->worker_id(), "host-17b, host-17 (refused)");
  activity.WorkerSeen("host-17", "ipv4:10.0.0.7:4242", 8, "v1");
  ASSERT_TRUE(RefusedAt(activity.Workers(), "10.0.0.7").has_value());
  EXPECT_EQ(RefusedAt(activity.Workers(), "10.0.0.7")->worker_id(), "host-17b");
  std::optional<v1::WorkerInfo> accepted = Find(activity.Workers(), "host-17");
  ASSERT_TRUE(accepted.has_value());
  EXPECT_FALSE(accepted->refused());
  EXPECT_EQ(accepted->refused_calls(), 0u);
  // ... and the entry goes with its last id.
  activity.WorkerSeen("host-17b", "ipv4:10.0.0.7:4243", 8, "v1");
  EXPECT_FALSE(RefusedAt(activity.Workers(), "10.0.0.7").has_value());
  EXPECT_TRUE(RefusedAt(activity.Workers(), "10.0.0.8").has_value());
}

TEST(FarmActivity, WhereTheAddressIsNotKnownRefusalsAreCountedPerAnnouncedId) {
  FakeClock clock;
  FarmActivity activity(clock);
  EXPECT_TRUE(activity.WorkerRefused("", "w-x", kInvalid));
  EXPECT_FALSE(activity.WorkerRefused("", "w-x", kInvalid));
  EXPECT_TRUE(activity.WorkerRefused("", "w-y", kInvalid));
  std::optional<v1::WorkerInfo> x = Find(activity.Workers(), "w-x");
  ASSERT_TRUE(x.has_value());
  EXPECT_TRUE(x->refused());
  EXPECT_EQ(x->peer(), "");
  EXPECT_EQ(x->refused_calls(), 2u);
  EXPECT_EQ(Find(activity.Workers(), "w-y")->refused_calls(), 1u);
  // Accepted from any address: its entry without an address goes.
  activity.WorkerSeen("w-x", "ipv4:10.0.0.5:1", 2, "v1");
  x = Find(activity.Workers(), "w-x");
  ASSERT_TRUE(x.has_value());
  EXPECT_FALSE(x->refused());
  EXPECT_EQ(x->peer(), "ipv4:10.0.0.5:1");
  EXPECT_FALSE(Find(activity.Workers(), "w-x (refused)").has_value()) << "its refused entry stayed";
  ASSERT_TRUE(Find(activity.Workers(), "w-y").has_value());
  EXPECT_TRUE(Find(activity.Workers(), "w-y")->refused());
}

TEST(FarmActivity, AnIdLongerThanAnAnnouncedOneIsRecognisedByItsAnnouncedForm) {
  // pf-worker-id carries at most 64 bytes of the id; LeaseTask carries it whole (up to 256).
  FakeClock clock;
  FarmActivity activity(clock);
  const std::string id = "render-node." + std::string(80, 'd') + ".example-1234";
  activity.WorkerRefused("10.0.0.7", id, kInvalid);
  activity.WorkerRefused("", id, kInvalid);
  activity.WorkerSeen("other", "ipv4:10.0.0.2:1", 2, "v1");
  EXPECT_EQ(CountRefused(activity.Workers()), 2u);
  activity.WorkerSeen(id, "ipv4:10.0.0.7:4242", 8, "v1");
  EXPECT_EQ(CountRefused(activity.Workers()), 0u)
      << "the worker's accepted poll cleared neither of its refused entries";
  // Its name is recognised in its announced form: a refused caller announcing it is marked.
  activity.WorkerRefused("10.6.6.6", id, kInvalid);
  ASSERT_TRUE(RefusedAt(activity.Workers(), "10.6.6.6").has_value());
  EXPECT_EQ(RefusedAt(activity.Workers(), "10.6.6.6")->worker_id(), id.substr(0, 64) + " (refused)");
}

TEST(FarmActivity, AnAnnouncedIdIsUntrustedAndCannotTakeOverALiveWorker) {
  FakeClock clock;
  FarmActivity activity(clock);
  activity.WorkerSeen("render-3", "ipv4:10.0.0.3:5000", 4, "v1");
  activity.WorkerRefused("10.6.6.6", "render-3", kInvalid);
  std::vector<v1::WorkerInfo> workers = activity.Workers();
  ASSERT_TRUE(Find(workers, "render-3").has_value());
  EXPECT_FALSE(Find(workers, "render-3")->refused()) << "the live worker's entry was taken over";
  EXPECT_EQ(Find(workers, "render-3")->peer(), "ipv4:10.0.0.3:5000");
  ASSERT_TRUE(Find(workers, "render-3 (refused)").has_value());
  EXPECT_EQ(Find(workers, "render-3 (refused)")->peer(), "10.6.6.6");
  // Also once the worker has been silent for long: the name stays the worker's.
  clock.Advance(3600);
  activity.WorkerRefused("10.6.6.6", "render-3", kInvalid);
  EXPECT_FALSE(Find(activity.Workers(), "render-3")->refused());
  EXPECT_EQ(Find(activity.Workers(), "render-3 (refused)")->refused_calls(), 2u);
  // No id, and ids that are long or not printable; at most kMaxRefusedIdsPerAddress ids listed.
  activity.WorkerRefused("10.0.0.1", "",
                         "UNAUTHENTICATED: authorization: missing (expected 'Bearer <token>')");
  EXPECT_TRUE(Find(activity.Workers(), "(no worker id)").has_value());
  activity.WorkerRefused("10.0.0.2", std::string(500, 'x'), kInvalid);
  EXPECT_TRUE(Find(activity.Workers(), std::string(64, 'x')).has_value());
  activity.WorkerRefused("10.0.0.3", "bad\nid\x01", kInvalid);
  EXPECT_TRUE(Find(activity.Workers(), "bad?id?").has_value());
  for (int i = 0; i < 10; ++i) activity.WorkerRefused("10.0.0.4", "id-" + std::to_string(i), kInvalid);
  ASSERT_TRUE(RefusedAt(activity.Workers(), "10.0.0.4").has_value());
  EXPECT_EQ(RefusedAt(activity.Workers(), "10.0.0.4")->worker_id(), "id-9, id-8, id-7, id-6");
}

TEST(FarmActivity, AFloodOfRefusedCallersNeverPushesAWorkerOut) {
  FakeClock clock;
  FarmActivity activity(clock);
  for (int i = 0; i < 50; ++i) activity.WorkerSeen("node-" + std::to_string(i), "ipv4:10.0.0.1:1", 2, "v1");
  // One address with any number of made-up ids is one entry; many addresses are at most kMaxRefusedKept.
  for (int i = 0; i < 20000; ++i)
    activity.WorkerRefused("10.9.9.9", "made-up-" + std::to_string(i), kInvalid);
  for (int i = 0; i < 2000; ++i) {
    clock.Advance(0.001);
    activity.WorkerRefused("10.1." + std::to_string(i / 256) + "." + std::to_string(i % 256), "x", kInvalid);
  }
  const std::vector<v1::WorkerInfo> workers = activity.Workers();
  EXPECT_EQ(CountRefused(workers), kMaxRefusedKept);
  for (int i = 0; i < 50; ++i) EXPECT_TRUE(Find(workers, "node-" + std::to_string(i)).has_value()) << i;
  EXPECT_TRUE(RefusedAt(workers, "10.1.7.207").has_value()) << "the most recent refusal is kept";
  EXPECT_FALSE(RefusedAt(workers, "10.1.0.0").has_value());
  EXPECT_FALSE(RefusedAt(workers, "10.9.9.9").has_value()) << "the least recently refused address goes first";
}

TEST(FarmActivity, MadeUpIdsWithoutAnAddressNeverPushOutTheAddresses) {
  FakeClock clock;
  FarmActivity activity(clock);
  for (int i = 0; i < 10; ++i) {
    clock.Advance(1);
    activity.WorkerRefused("10.2.0." + std::to_string(i), "w", kInvalid);
  }
  for (int i = 0; i < 5000; ++i) {
    clock.Advance(0.001);
    activity.WorkerRefused("", "made-up-" + std::to_string(i), kInvalid);
  }
  const std::vector<v1::WorkerInfo> workers = activity.Workers();
  EXPECT_EQ(CountRefused(workers), kMaxRefusedKept);
  for (int i = 0; i < 10; ++i)
    EXPECT_TRUE(RefusedAt(workers, "10.2.0." + std::to_string(i)).has_value()) << i;
  EXPECT_TRUE(Find(workers, "made-up-4999").has_value());
}

}  // namespace
}  // namespace pf::server

// Events and worker statistics outlive a restart (docs/farm.md "Activity across restarts"): taken
// in batches into a real SQLite file, restored by a new FarmActivity on the same file — the counts and
// events as they were, no worker busy, each lost until it polls, no quarantine or blocklist (this
// life's worker health starts without them), a deleted job's events gone (also those arriving after
// its deletion), each job's newest events kept, evicted workers forgotten in the store too.
#include "server/store/sqlite_store.h"
#include "tests/util/temp_dir.h"

namespace pf::server {
namespace {

TEST(FarmActivityPersistence, EventsAndWorkerStatisticsComeBackFromTheStore) {
  test_util::TempDir dir("pf_activity");
  const auto db_file = dir.path() / "coordinator.db";
  {
    FakeClock clock;
    FarmActivity activity(clock);
    SqliteStore db(db_file);
    uint64_t seq = 0;
    for (const char* job : {"job-a", "job-b", "job-c", "job-d"}) {
      JobRow row;
      row.job_id = job;
      row.seq = ++seq;
      db.InsertJob(row, {});
    }
    activity.WorkerSeen("w1", "ipv4:10.0.0.7:4242", 8, "v1");
    activity.TaskEvent("job-a", "leased", 3, 1, "w1");
    activity.TaskEvent("job-a", "merged", 3, 1, "w1", "0.5 s");
    activity.WorkerStats("w1", 1000, 2.0);
    db.SaveActivity(activity.TakeChanges(), kMaxEventsPerJob);
    EXPECT_TRUE(activity.TakeChanges().empty()) << "nothing changed since";
    activity.TaskEvent("job-a", "leased", 4, 1, "w1");  // busy now
    activity.TaskEvent("job-b", "failed", 0, 2, "w2", "out of memory");
    activity.WorkerLost("w2", true);
    activity.WorkerBlocklisted("w2", "job-b");
    activity.WorkerQuarantined("w2", clock.Now() + 600, "3 jobs failed");
    clock.Advance(5);
    db.SaveActivity(activity.TakeChanges(), kMaxEventsPerJob);
    // A job deleted with its events; a third job with more events than are kept.
    activity.TaskEvent("job-c", "leased", 0, 1, "w1");
    db.SaveActivity(activity.TakeChanges(), kMaxEventsPerJob);
    db.DeleteJob("job-c");
    activity.TaskEvent("job-c", "merged", 0, 1, "w1");  // on its way while the job was deleted
    db.SaveActivity(activity.TakeChanges(), kMaxEventsPerJob);
    for (int i = 0; i < 5; ++i) activity.TaskEvent("job-d", "leased", uint64_t(i), 1, "");
    db.SaveActivity(activity.TakeChanges(), /*max_events_per_job=*/3);
  }
  FakeClock clock;
  clock.Advance(7);  // the new life's clock is later
  FarmActivity restored(clock);
  SqliteStore db(db_file);
  restored.Restore(db.LoadActivity());

  const std::vector<v1::TaskEvent> a = restored.Events("job-a");
  ASSERT_EQ(a.size(), 3u);
  EXPECT_EQ(a[1].kind(), "merged");
  EXPECT_EQ(a[1].detail(), "0.5 s");
  EXPECT_EQ(restored.Events("job-b").at(0).detail(), "out of memory");
  EXPECT_TRUE(restored.Events("job-c").empty()) << "deleted with its job";
  const std::vector<v1::TaskEvent> d = restored.Events("job-d");
  ASSERT_EQ(d.size(), 3u);
  EXPECT_EQ(d.front().task_id(), 2u) << "the newest three";

  const std::optional<v1::WorkerInfo> w1 = Find(restored.Workers(), "w1");
  ASSERT_TRUE(w1.has_value());
  EXPECT_EQ(w1->tasks_done(), 2u);  // job-a task 3, job-c task 0
  EXPECT_EQ(w1->photons_emitted(), 1000u);
  EXPECT_EQ(w1->peer(), "ipv4:10.0.0.7:4242");
  EXPECT_FALSE(w1->busy()) << "its lease ended with the coordinator";
  EXPECT_TRUE(w1->lost()) << "not heard from in this life";
  EXPECT_NEAR(w1->seconds_since_seen(), 2.0, 1e-3) << "seen when it was last seen: its lease of job-c at 5 s";
  const std::optional<v1::WorkerInfo> w2 = Find(restored.Workers(), "w2");
  ASSERT_TRUE(w2.has_value());
  EXPECT_TRUE(w2->lost());
  EXPECT_EQ(w2->tasks_failed(), 1u);
  EXPECT_EQ(w2->blocklisted_job_ids_size(), 0) << "not enforced in this life: not shown";
  EXPECT_FALSE(w2->quarantined());
  // Lost as the last life saw it, until it polls again (this life's health never marked it).
  restored.WorkerSeen("w2", "ipv4:10.0.0.8:1", 4, "v1");
  EXPECT_FALSE(Find(restored.Workers(), "w2")->lost());

  // A batch the store could not take is put back, older than what came since.
  restored.TaskEvent("job-a", "expired", 4, 1, "w1");
  ActivityRecords batch = restored.TakeChanges();
  restored.TaskEvent("job-a", "leased", 4, 2, "w2");
  restored.ReturnChanges(std::move(batch));
  const ActivityRecords again = restored.TakeChanges();
  ASSERT_EQ(again.events.size(), 2u);
  v1::TaskEvent first;
  ASSERT_TRUE(first.ParseFromString(again.events[0].bytes));
  EXPECT_EQ(first.kind(), "expired");
  EXPECT_FALSE(again.workers.empty());
}

}  // namespace
}  // namespace pf::server
