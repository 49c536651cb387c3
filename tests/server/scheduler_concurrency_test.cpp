// The scheduler with results merged off its global lock (scheduler.h, "Locks"): many threads
// completing tasks of one or two jobs give exactly the accumulator of a serial merge; a result
// is decided exactly once when its lease expires, its job is cancelled, the worker fails the
// task or a second copy arrives while the result is being checked; a checkpoint taken while
// results are merged always agrees with its list of merged tasks.
#include <gtest/gtest.h>

#include <atomic>
#include <cstring>
#include <map>
#include <thread>

#include "server/clock.h"
#include "server/scheduling/scheduler.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using testing::MakeConfig;
using testing::MultipleMaps;
using testing::Skipping;
using testing::SyntheticResult;
namespace v1 = photonfarm::v1;

constexpr int kThreads = 8;

std::string WorkerName(size_t i) {
  static const char* const kNames[] = {"w0", "w1", "w2", "w3", "w4", "w5", "w6", "w7"};
  return kNames[i % 8];
}

class SchedulerConcurrencyTest : public testing::SchedulerFixture {
 protected:
  std::vector<Lease> LeaseAll() {
    std::vector<Lease> leases;
    while (std::optional<Lease> l = scheduler_.TryLease({WorkerName(leases.size() % 5), {}}))
      leases.push_back(std::move(*l));
    return leases;
  }
  static std::vector<float> ResultOf(const Lease& lease) {
    return SyntheticResult(lease.task, lease.config->camera.width, lease.config->camera.height);
  }
};

// The job's tasks merged one after another into a fresh accumulator: the reference.
Accumulator SerialMerge(const JobConfig& config, const std::vector<Lease>& leases,
                        const std::string& job_id) {
  Accumulator acc(config.plan, config.camera.width, config.camera.height, config.settings.progressive_alpha);
  ResultMerger merger;
  std::map<uint64_t, const Lease*> by_task;
  for (const Lease& l : leases)
    if (l.job_id == job_id) by_task[l.task_id] = &l;
  for (const auto& [id, lease] : by_task) {
    const std::vector<float> sums = SyntheticResult(lease->task, config.camera.width, config.camera.height);
    const CheckedResult checked =
        ResultMerger::Check(lease->task, config.camera.width, config.camera.height, sums);
    EXPECT_TRUE(checked.valid.has_value()) << checked.problem;
    merger.Merge(*checked.valid, acc);
  }
  return acc;
}

// Bit for bit: the resolved image (from the exact fixed-point sums) and the counts.
void ExpectSameImage(Scheduler& scheduler, const std::string& job_id, const Accumulator& reference) {
  const JobSnapshot snap = scheduler.Snapshot(job_id, /*with_image=*/true);
  ASSERT_TRUE(snap.image.has_value()) << job_id;
  EXPECT_EQ(snap.image->samples_merged, reference.samples_merged()) << job_id;
  EXPECT_EQ(snap.status.samples_merged(), reference.samples_merged()) << job_id;
  const Image expected = reference.Resolve();
  ASSERT_EQ(snap.image->image.size(), expected.size());
  EXPECT_EQ(
      std::memcmp(snap.image->image.pixels().data(), expected.pixels().data(), expected.size() * sizeof(Rgb)),
      0)
      << job_id << ": merged image differs from the serial merge";
}

// Every lease completed twice, by different threads at once, in a shuffled order.
TEST_F(SchedulerConcurrencyTest, ConcurrentCompletionsOfOneJobEqualTheSerialMerge) {
  const JobConfig config = MakeConfig(MultipleMaps(24, 8, 2), 48, 40);
  const std::string id = Submit(config);
  const std::vector<Lease> leases = LeaseAll();
  ASSERT_EQ(leases.size(), 24u * 6 * 5);
  std::vector<std::vector<float>> results;
  for (const Lease& l : leases) results.push_back(ResultOf(l));

  std::atomic<size_t> next{0}, merged{0}, ignored{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&] {
      for (size_t i; (i = next.fetch_add(1)) < 2 * leases.size();) {
        const size_t k = (i / 2 * 7919) % leases.size();  // each lease twice, in a scattered order
        const CompleteResult r = scheduler_.Complete(leases[k].lease_id, leases[k].worker_id, results[k]);
        (r.status == CompleteStatus::kMerged ? merged : ignored).fetch_add(1);
        EXPECT_NE(r.status, CompleteStatus::kRejected) << r.reason;
      }
    });
  for (std::thread& t : threads) t.join();

  EXPECT_EQ(merged.load(), leases.size());
  EXPECT_EQ(ignored.load(), leases.size());
  EXPECT_EQ(scheduler_.counters().merged, leases.size());
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  ExpectSameImage(scheduler_, id, SerialMerge(config, leases, id));
}

// Workers leasing and completing at once, for two jobs (one of them skipping), while the
// persister's checkpoints and status calls run beside them.
TEST_F(SchedulerConcurrencyTest, ConcurrentLeasesAndCompletionsOfTwoJobsEqualTheSerialMerge) {
  const JobConfig a = MakeConfig(MultipleMaps(16, 8, 1), 40, 32);
  const JobConfig b = MakeConfig(Skipping(3, 8, 2), 33, 27);
  const std::string id_a = Submit(a), id_b = Submit(b);

  std::mutex leases_mu;
  std::vector<Lease> done;
  std::atomic<bool> stop_persist{false};
  std::atomic<size_t> checkpoints{0};
  auto collect = [&] {
    for (const Checkpoint& cp : scheduler_.CollectCheckpoints(/*due=*/true)) {
      const JobConfig& c = cp.job_id == id_a ? a : b;
      const Accumulator acc = Accumulator::Deserialize(cp.accumulator, &c.plan);
      // Commit and add lie within one hold of image_mu: the list and the image agree.
      EXPECT_EQ(acc.tasks_merged(), cp.merged_task_ids.size()) << cp.job_id;
      checkpoints.fetch_add(1);
    }
  };
  std::thread persist([&] {
    while (!stop_persist.load()) {
      collect();
      scheduler_.Status(id_a);
      scheduler_.List(true);
    }
  });
  std::vector<std::thread> workers;
  for (int t = 0; t < kThreads; ++t)
    workers.emplace_back([&, t] {
      while (std::optional<Lease> lease = scheduler_.TryLease({WorkerName(size_t(t)), {}})) {
        const std::vector<float> sums = ResultOf(*lease);
        EXPECT_EQ(scheduler_.Complete(lease->lease_id, lease->worker_id, sums).status,
                  CompleteStatus::kMerged);
        std::lock_guard lock(leases_mu);
        done.push_back(std::move(*lease));
      }
    });
  for (std::thread& t : workers) t.join();
  stop_persist = true;
  persist.join();
  collect();  // the final checkpoints (how many the loop saw depends on the machine's load)

  EXPECT_GT(checkpoints.load(), 0u);
  EXPECT_EQ(scheduler_.Status(id_a).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id_b).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(done.size(), 16u * 5 * 4 + 8u * 9);
  ExpectSameImage(scheduler_, id_a, SerialMerge(a, done, id_a));
  ExpectSameImage(scheduler_, id_b, SerialMerge(b, done, id_b));
}

// The lease runs out (and Tick runs) while its result is being checked: the result arrived in
// time, so it is merged once, the task is not re-queued and nothing expires.
TEST_F(SchedulerConcurrencyTest, LeaseExpiringWhileItsResultIsMergedCountsOnce) {
  const JobConfig config = MakeConfig(MultipleMaps(2, 0), 8, 8);
  const std::string id = Submit(config);
  const Lease first = scheduler_.TryLease({"w1", {}}).value();
  bool hooked = false;
  probe_.Set([&](const std::string& lease_id) {
    if (lease_id != first.lease_id || hooked) return;
    hooked = true;
    clock_.Advance(31);
    scheduler_.Tick();
    EXPECT_TRUE(scheduler_.Extend(first.lease_id, first.worker_id, 0.5).ok)
        << "a pinned lease does not expire";
    // The other task is leased, this one must not be leased again.
    const std::optional<Lease> other = scheduler_.TryLease({"w2", {}});
    ASSERT_TRUE(other.has_value());
    EXPECT_NE(other->task_id, first.task_id);
    EXPECT_FALSE(scheduler_.TryLease({"w3", {}}).has_value());
  });
  EXPECT_EQ(scheduler_.Complete(first.lease_id, first.worker_id, ResultOf(first)).status,
            CompleteStatus::kMerged);
  ASSERT_TRUE(hooked);
  EXPECT_EQ(scheduler_.counters().expired, 0u);
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 1u);
  // The same result again: decided already.
  EXPECT_EQ(scheduler_.Complete(first.lease_id, first.worker_id, ResultOf(first)).status,
            CompleteStatus::kIgnored);
  EXPECT_EQ(scheduler_.counters().merged, 1u);
  EXPECT_EQ(scheduler_.Status(id).samples_merged(), 64u);
}

// A lease that expired before its result arrived was re-leased: the late result is ignored, the
// new holder's merged, the task counted once.
TEST_F(SchedulerConcurrencyTest, ResultOfAReassignedLeaseIsIgnoredOnce) {
  const JobConfig config = MakeConfig(MultipleMaps(1, 0), 8, 8);
  const std::string id = Submit(config);
  const Lease first = scheduler_.TryLease({"w1", {}}).value();
  clock_.Advance(31);
  scheduler_.Tick();
  const Lease second = scheduler_.TryLease({"w2", {}}).value();
  ASSERT_EQ(second.task_id, first.task_id);
  std::vector<std::thread> threads;
  std::atomic<int> merged{0}, ignored{0};
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      const Lease& l = t % 2 ? first : second;
      const CompleteResult r = scheduler_.Complete(l.lease_id, l.worker_id, ResultOf(l));
      (r.status == CompleteStatus::kMerged ? merged : ignored).fetch_add(1);
      if (r.status == CompleteStatus::kMerged) {
        EXPECT_EQ(r.worker_id, "w2");
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(merged.load(), 1);
  EXPECT_EQ(ignored.load(), kThreads - 1);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id).samples_merged(), 64u);
}

// Cancelled while a result was being checked: the late result is dropped, nothing merged, no
// image allocated.
TEST_F(SchedulerConcurrencyTest, ResultOfAJobCancelledWhileItWasCheckedIsDropped) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 8, 8));
  const Lease lease = scheduler_.TryLease({"w1", {}}).value();
  probe_.Set([&](const std::string&) { scheduler_.Cancel(id); });
  const CompleteResult r = scheduler_.Complete(lease.lease_id, lease.worker_id, ResultOf(lease));
  EXPECT_EQ(r.status, CompleteStatus::kIgnored);
  EXPECT_EQ(r.reason, "the job ended while the result was checked");
  const JobSnapshot snap = scheduler_.Snapshot(id, true);
  EXPECT_EQ(snap.status.state(), v1::JOB_STATE_CANCELLED);
  EXPECT_EQ(snap.status.tasks_done(), 0u);
  EXPECT_EQ(snap.status.samples_merged(), 0u);
  EXPECT_FALSE(snap.image.has_value());
  EXPECT_EQ(scheduler_.counters().merged, 0u);
  EXPECT_EQ(scheduler_.counters().ignored, 1u);
}

// An exception while a result is checked (between claim and commit: an allocation failing, here
// the test hook) leaves the lease live and unpinned: it expires as any lease would, and a second
// delivery of the result is merged once. Without the guard the lease stayed pinned for ever (it
// never expired, every result was "already being merged") and the job never finished.
TEST_F(SchedulerConcurrencyTest, AnExceptionWhileAResultIsCheckedLeavesTheLeaseLive) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 8, 8));
  const Lease lease = scheduler_.TryLease({"w1", {}}).value();
  const std::vector<float> sums = ResultOf(lease);
  bool thrown = false;
  probe_.Set([&](const std::string&) {
    if (thrown) return;
    thrown = true;
    throw std::bad_alloc();
  });
  EXPECT_THROW(scheduler_.Complete(lease.lease_id, lease.worker_id, sums), std::bad_alloc);
  EXPECT_EQ(scheduler_.counters().merged, 0u);
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 0u);
  EXPECT_EQ(scheduler_.Complete(lease.lease_id, lease.worker_id, sums).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id).samples_merged(), 64u);

  // The same, and then the lease runs out: it expires (it is not pinned) and runs again.
  const std::string id2 = Submit(MakeConfig(MultipleMaps(1, 0), 8, 8));
  const Lease second = scheduler_.TryLease({"w1", {}}).value();
  thrown = false;
  EXPECT_THROW(scheduler_.Complete(second.lease_id, second.worker_id, ResultOf(second)), std::bad_alloc);
  clock_.Advance(31);
  scheduler_.Tick();
  const std::optional<Lease> again = scheduler_.TryLease({"w2", {}});
  ASSERT_TRUE(again.has_value()) << "the lease expired and the task is leased again";
  EXPECT_EQ(again->task_id, second.task_id);
  EXPECT_EQ(scheduler_.Complete(again->lease_id, again->worker_id, ResultOf(*again)).status,
            CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id2).samples_merged(), 64u);
}

// While a result is checked, a second copy is ignored and FailTask from its holder changes
// nothing; the first copy is merged.
TEST_F(SchedulerConcurrencyTest, SecondCopyAndFailTaskWhileAResultIsCheckedChangeNothing) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 8, 8));
  const Lease lease = scheduler_.TryLease({"w1", {}}).value();
  const std::vector<float> sums = ResultOf(lease);
  int depth = 0;
  probe_.Set([&](const std::string&) {
    if (depth++ > 0) return;
    const CompleteResult copy = scheduler_.Complete(lease.lease_id, lease.worker_id, sums);
    EXPECT_EQ(copy.status, CompleteStatus::kIgnored);
    EXPECT_EQ(copy.reason, "a result for this lease is already being merged");
    EXPECT_EQ(scheduler_.Fail(lease.lease_id, "w1", "oops", /*retryable=*/false), FailOutcome::kUnknownLease);
    scheduler_.ReturnLease(lease.lease_id);
    EXPECT_EQ(scheduler_.Status(id).tasks_running(), 1u);
  });
  EXPECT_EQ(scheduler_.Complete(lease.lease_id, lease.worker_id, sums).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.counters().merged, 1u);
  EXPECT_EQ(scheduler_.counters().failed_attempts, 0u);
}

// A rejected result found off the lock still fails exactly its attempt.
TEST_F(SchedulerConcurrencyTest, InvalidResultsFromManyThreadsFailTheirAttemptsOnce) {
  const std::string id = Submit(MakeConfig(MultipleMaps(8, 4), 8, 8));
  // One worker per lease: a worker with 3 rejected results would be blocklisted for the job
  // (worker_health.h), which is not what this test is about.
  std::vector<Lease> leases;
  auto worker = [&] { return std::string("u").append(std::to_string(leases.size())); };
  while (std::optional<Lease> l = scheduler_.TryLease({worker(), {}})) leases.push_back(std::move(*l));
  ASSERT_EQ(leases.size(), 8u * 4);
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      for (size_t k = size_t(t); k < leases.size(); k += kThreads) {
        std::vector<float> sums = ResultOf(leases[k]);
        sums[1] = -1.0f;  // negative radiance: invalid
        EXPECT_EQ(scheduler_.Complete(leases[k].lease_id, leases[k].worker_id, sums).status,
                  CompleteStatus::kRejected);
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(scheduler_.counters().failed_attempts, leases.size());
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.tasks_queued(), leases.size());
  EXPECT_EQ(s.samples_merged(), 0u);
  // Each retried once more: the second lease of every task is attempt 2.
  for (const Lease& l : LeaseAll()) EXPECT_EQ(l.attempt, 2u);
}

}  // namespace
}  // namespace pf::server
