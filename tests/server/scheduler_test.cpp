// The scheduler's rules with a FakeClock (no sleeping): leases, heartbeats, expiry and attempts,
// bounded retries, idempotent results, priorities, map affinity, long polls, stop rules.
#include "server/scheduling/scheduler.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <optional>
#include <set>

#include "common/core/rng.h"
#include "common/plan/hierarchical.h"
#include "server/clock.h"
#include "server/errors.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using ::testing::HasSubstr;
using testing::MakeConfig;
using testing::MultipleMaps;
using testing::Skipping;
using testing::SyntheticResult;
namespace v1 = photonfarm::v1;

class SchedulerTest : public testing::SchedulerFixture {
 protected:
  Lease MustLease(const std::string& worker = "w1", std::vector<uint64_t> seeds = {}) {
    std::optional<Lease> lease = scheduler_.TryLease({worker, std::move(seeds)});
    EXPECT_TRUE(lease.has_value());
    return lease.value_or(Lease{});
  }
  CompleteResult CompleteOk(const Lease& lease) {
    if (!lease.config) {  // MustLease failed (and said so)
      ADD_FAILURE() << "no lease to complete";
      return {};
    }
    const auto& cam = lease.config->camera;
    const std::vector<float> sums = SyntheticResult(lease.task, cam.width, cam.height);
    return scheduler_.Complete(lease.lease_id, lease.worker_id, sums);
  }
};

TEST_F(SchedulerTest, JobRunsFromQueuedToSucceeded) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 8, 4));
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(scheduler_.Status(id).tasks_total(), 2u);
  const Lease a = MustLease();
  EXPECT_EQ(a.attempt, 1u);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(scheduler_.Status(id).tasks_running(), 1u);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  const Lease b = MustLease();
  EXPECT_NE(a.task_id, b.task_id);
  EXPECT_EQ(CompleteOk(b).status, CompleteStatus::kMerged);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), 2u);
  EXPECT_EQ(s.samples_merged(), 2u * 8 * 4);
  EXPECT_GE(s.estimated_noise_rms(), 0.0);  // two maps cover every pixel
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value());
}

TEST_F(SchedulerTest, ExpiredLeaseIsRequeuedWithTheNextAttempt) {
  Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease first = MustLease("w1");
  clock_.Advance(29.9);
  scheduler_.Tick();
  EXPECT_FALSE(scheduler_.TryLease({"w2", {}}).has_value()) << "still leased before expiry";
  clock_.Advance(0.2);
  scheduler_.Tick();
  const Lease second = MustLease("w2");
  EXPECT_EQ(second.task_id, first.task_id);
  EXPECT_EQ(second.attempt, 2u);
  EXPECT_NE(second.lease_id, first.lease_id);
  EXPECT_EQ(scheduler_.counters().expired, 1u);
  // The first worker's lease is gone: heartbeat says stop, its result is ignored.
  EXPECT_FALSE(scheduler_.Extend(first.lease_id, first.worker_id, 0.5).ok);
  const CompleteResult late = CompleteOk(first);
  EXPECT_EQ(late.status, CompleteStatus::kIgnored);
  EXPECT_EQ(CompleteOk(second).status, CompleteStatus::kMerged);
}

TEST_F(SchedulerTest, ExpiryIsNoticedWhenTheLeaseIsUsedEvenWithoutATick) {
  Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease first = MustLease();
  clock_.Advance(31);
  EXPECT_EQ(CompleteOk(first).status, CompleteStatus::kIgnored);
  EXPECT_EQ(MustLease().attempt, 2u);
}

TEST_F(SchedulerTest, HeartbeatExtendsTheLease) {
  Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease lease = MustLease();
  for (int i = 0; i < 5; ++i) {
    clock_.Advance(20);
    const ExtendResult r = scheduler_.Extend(lease.lease_id, lease.worker_id, 0.1 * i);
    EXPECT_TRUE(r.ok);
    EXPECT_EQ(r.lease_seconds, 30);
    scheduler_.Tick();
  }
  // 100 s after the lease started it is still alive thanks to the heartbeats.
  EXPECT_FALSE(scheduler_.TryLease({"w2", {}}).has_value());
  EXPECT_EQ(CompleteOk(lease).status, CompleteStatus::kMerged);
}

TEST_F(SchedulerTest, TooManyFailedAttemptsFailTheJobWithTheReason) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const Lease lease = MustLease();
    ASSERT_EQ(lease.task_id, 0u);
    ASSERT_EQ(lease.attempt, attempt);
    clock_.Advance(31);
    scheduler_.Tick();
  }
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("task 0 attempt 3 failed: lease expired (worker w1)"));
  EXPECT_THAT(s.failure_reason(), HasSubstr("gave up after 3 failed attempts"));
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value()) << "a failed job's other tasks are cancelled";
}

TEST_F(SchedulerTest, FailTaskRetriesThenNonRetryableFailsAtOnce) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease a = MustLease();
  EXPECT_EQ(scheduler_.Fail(a.lease_id, "w1", "out of memory", /*retryable=*/true), FailOutcome::kFailed);
  EXPECT_EQ(scheduler_.Fail(a.lease_id, "w1", "again", true), FailOutcome::kUnknownLease)
      << "the lease is gone";
  const Lease b = MustLease();
  EXPECT_EQ(b.attempt, 2u);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(scheduler_.Fail(b.lease_id, "w1", "scene does not load", /*retryable=*/false),
            FailOutcome::kFailed);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("worker: scene does not load (not retryable)"));
}

// Only the lease's holder can fail its task: another worker presenting the lease id (even with
// retryable = false) and an unknown lease id change nothing; the holder's result still merges.
TEST_F(SchedulerTest, OnlyTheLeaseHolderCanFailItsTask) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease a = MustLease("holder");
  EXPECT_EQ(scheduler_.Fail(a.lease_id, "stranger", "kill the job", /*retryable=*/false),
            FailOutcome::kNotHolder);
  EXPECT_EQ(scheduler_.Fail(a.lease_id + "x", "holder", "kill the job", false), FailOutcome::kUnknownLease);
  v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(scheduler_.counters().failed_attempts, 0u);
  // Presenting another worker's lease blocklists the presenter for the job (docs/security.md);
  // the job goes on.
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "stranger");
  EXPECT_EQ(scheduler_.JobEpoch(id), 0u);
  EXPECT_FALSE(scheduler_.TryLease({"stranger", {}}).has_value());
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged) << "the holder's lease is intact";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// A result above the job's bound (samples × max_sample_radiance) is not merged and
// the task is re-run; it is merged when a *different* worker delivers the same bytes (rendering is
// deterministic, so an honest result above the bound reproduces), never on different bytes.
TEST_F(SchedulerTest, ResultsAboveTheBoundMergeOnlyWhenAnotherWorkerReproducesThem) {
  JobConfig config = MakeConfig(MultipleMaps(1, 0), 4, 4);
  config.max_sample_radiance = 10;  // SyntheticResult stays below 2 per sample
  const std::string id = Submit(config);
  auto huge = [&](const Lease& lease, float value) {
    std::vector<float> sums = SyntheticResult(lease.task, 4, 4);
    sums[5] = value;
    return sums;
  };
  const Lease a = MustLease("w1");
  CompleteResult r = scheduler_.Complete(a.lease_id, a.worker_id, huge(a, 1e8f));
  EXPECT_EQ(r.status, CompleteStatus::kRejected);
  EXPECT_THAT(r.reason, HasSubstr("rgb_sums[5] = 1e+08 exceeds the job's bound 10 (1 samples x 10)"));
  EXPECT_THAT(r.reason, HasSubstr("merged only if another worker reproduces it exactly"));
  const Lease b = MustLease("w1");
  EXPECT_EQ(scheduler_.Complete(b.lease_id, b.worker_id, huge(b, 1e8f)).status, CompleteStatus::kRejected)
      << "the same worker cannot confirm its own result";
  const Lease c = MustLease("w2");
  EXPECT_EQ(scheduler_.Complete(c.lease_id, c.worker_id, huge(c, 2e8f)).status, CompleteStatus::kRejected)
      << "different bytes confirm nothing";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << "failed on 2 workers only";
  const Lease c3 = MustLease("w3");
  EXPECT_EQ(scheduler_.Complete(c3.lease_id, c3.worker_id, huge(c3, 3e8f)).status, CompleteStatus::kRejected);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_FAILED) << "failed on 3 workers";

  // Again with max_attempts room: w2's bytes reproduced by w3 are merged.
  const std::string id2 = Submit(config);
  const Lease d = MustLease("w2");
  EXPECT_EQ(scheduler_.Complete(d.lease_id, d.worker_id, huge(d, 2e8f)).status, CompleteStatus::kRejected);
  const Lease e = MustLease("w3");
  r = scheduler_.Complete(e.lease_id, e.worker_id, huge(e, 2e8f));
  EXPECT_EQ(r.status, CompleteStatus::kMerged) << r.reason;
  EXPECT_EQ(scheduler_.Status(id2).state(), v1::JOB_STATE_SUCCEEDED);
  bool confirmed = false;
  for (const v1::TaskEvent& ev : scheduler_.activity().Events(id2))
    confirmed |= ev.kind() == "confirmed" && ev.worker_id() == "w3";
  EXPECT_TRUE(confirmed);
}

TEST_F(SchedulerTest, DuplicateResultsAreIgnoredAndMergedOnce) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  const Lease a = MustLease();
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kIgnored);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kIgnored);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.tasks_done(), 1u);
  EXPECT_EQ(s.samples_merged(), 16u);
  EXPECT_EQ(scheduler_.counters().ignored, 2u);
  const JobSnapshot snap = scheduler_.Snapshot(id, true);
  ASSERT_TRUE(snap.image.has_value());
  EXPECT_EQ(snap.image->metadata.at("tasks_merged"), "1");
}

TEST_F(SchedulerTest, LateResultAfterReassignmentIsIgnored) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease a = MustLease("slow");
  clock_.Advance(31);
  scheduler_.Tick();
  const Lease b = MustLease("fast");
  EXPECT_EQ(CompleteOk(b).status, CompleteStatus::kMerged);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kIgnored);
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 1u);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

TEST_F(SchedulerTest, RejectedResultsRequeueTheTaskWithTheNextAttempt) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease a = MustLease();
  const std::vector<float> short_result(5, 1.0f);
  CompleteResult r = scheduler_.Complete(a.lease_id, a.worker_id, short_result);
  EXPECT_EQ(r.status, CompleteStatus::kRejected);
  EXPECT_THAT(r.reason, HasSubstr("rgb_sums has 5 values, expected 48"));
  const Lease b = MustLease();
  EXPECT_EQ(b.task_id, a.task_id);
  EXPECT_EQ(b.attempt, 2u);
  std::vector<float> nan_result = SyntheticResult(b.task, 4, 4);
  nan_result[7] = std::nanf("");
  r = scheduler_.Complete(b.lease_id, b.worker_id, nan_result);
  EXPECT_EQ(r.status, CompleteStatus::kRejected);
  EXPECT_THAT(r.reason, HasSubstr("rgb_sums[7] is not finite"));
  const Lease c = MustLease();
  EXPECT_EQ(c.attempt, 3u);
  EXPECT_EQ(CompleteOk(c).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.counters().rejected, 2u);
  // Nothing of the rejected results reached the image.
  EXPECT_EQ(scheduler_.Status(id).samples_merged(), 16u);
}

TEST_F(SchedulerTest, HigherPriorityFirstThenSubmissionOrder) {
  const std::string low = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4, /*priority=*/0));
  const std::string high = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4, /*priority=*/5));
  const std::string low2 = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4, /*priority=*/0));
  const std::string negative = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4, /*priority=*/-3));
  EXPECT_EQ(MustLease().job_id, high);
  EXPECT_EQ(MustLease().job_id, low);
  EXPECT_EQ(MustLease().job_id, low2);
  EXPECT_EQ(MustLease().job_id, negative);
}

TEST_F(SchedulerTest, MapAffinityPrefersACachedMapWithinTheJob) {
  // 3 maps × 4 tiles: tasks 0-3 map 0, 4-7 map 1, 8-11 map 2.
  Submit(MakeConfig(MultipleMaps(3, 2), 4, 4));
  const Lease first = MustLease("w1");
  EXPECT_EQ(first.task_id, 0u);
  const Lease map2 = MustLease("w2");  // no cache: next in order
  EXPECT_EQ(map2.task_id, 1u);
  // w3 has map 2 cached: it gets map 2's first tile, not task 2.
  uint64_t map2_seed = MapSeed(7, 2);
  const Lease affine = MustLease("w3", {12345, map2_seed});
  EXPECT_EQ(affine.task.map_index, 2u);
  EXPECT_EQ(affine.task_id, 8u);
  // A seed of another job (or unknown) changes nothing.
  EXPECT_EQ(MustLease("w4", {999}).task_id, 2u);
}

TEST_F(SchedulerTest, LongPollIsAnsweredWhenATaskArrivesOrTheWaitEnds) {
  std::vector<std::optional<Lease>> answers;
  auto record = [&](std::optional<Lease> l) { answers.push_back(std::move(l)); };
  scheduler_.LeaseOrWait({"w1", {}}, 10, record);
  EXPECT_TRUE(answers.empty()) << "parked: no task yet";
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  ASSERT_EQ(answers.size(), 1u) << "submitting a job wakes the parked worker";
  ASSERT_TRUE(answers[0].has_value());
  EXPECT_EQ(answers[0]->job_id, id);

  scheduler_.LeaseOrWait({"w2", {}}, 5, record);
  clock_.Advance(4.9);
  scheduler_.Tick();
  EXPECT_EQ(answers.size(), 1u);
  clock_.Advance(0.2);
  scheduler_.Tick();
  ASSERT_EQ(answers.size(), 2u);
  EXPECT_FALSE(answers[1].has_value()) << "wait over: 'no task now'";

  const uint64_t waiter = scheduler_.LeaseOrWait({"w3", {}}, 5, record);
  scheduler_.CancelWait(waiter);
  ASSERT_EQ(answers.size(), 3u);
  EXPECT_FALSE(answers[2].has_value());
  scheduler_.CancelWait(waiter);  // idempotent
  EXPECT_EQ(answers.size(), 3u);

  // A re-queued task (expired lease) also wakes a parked worker.
  scheduler_.LeaseOrWait({"w4", {}}, 60, record);
  clock_.Advance(31);
  scheduler_.Tick();
  ASSERT_EQ(answers.size(), 4u);
  ASSERT_TRUE(answers[3].has_value());
  EXPECT_EQ(answers[3]->attempt, 2u);
}

TEST_F(SchedulerTest, ShutdownAnswersParkedPollsAndStopsLeasing) {
  std::vector<std::optional<Lease>> answers;
  scheduler_.LeaseOrWait({"w1", {}}, 10, [&](std::optional<Lease> l) { answers.push_back(std::move(l)); });
  scheduler_.Shutdown();
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_FALSE(answers[0].has_value());
  Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value());
}

TEST_F(SchedulerTest, ReturnedLeaseDoesNotCountAsAFailure) {
  Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  for (int i = 0; i < 5; ++i) scheduler_.ReturnLease(MustLease().lease_id);
  const Lease l = MustLease();
  EXPECT_EQ(l.attempt, 6u);  // attempt numbers only grow
  EXPECT_EQ(CompleteOk(l).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.counters().failed_attempts, 0u);
}

// Leases are bound to their worker (docs/security.md): another worker's heartbeat or result for
// a lease it does not hold changes nothing — the task is not kept alive for it, nothing is merged
// — and the holder's lease is intact.
TEST_F(SchedulerTest, OnlyTheLeaseHolderCanExtendOrCompleteItsTask) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease a = MustLease("holder");
  EXPECT_EQ(a.worker_id, "holder");
  clock_.Advance(20);
  const ExtendResult stranger = scheduler_.Extend(a.lease_id, "stranger", 0.5);
  EXPECT_FALSE(stranger.ok);
  EXPECT_TRUE(stranger.not_holder);
  const auto& cam = a.config->camera;
  const CompleteResult forged =
      scheduler_.Complete(a.lease_id, "stranger", SyntheticResult(a.task, cam.width, cam.height));
  EXPECT_EQ(forged.status, CompleteStatus::kNotHolder);
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 0u);
  clock_.Advance(11);  // 31 s after the lease: the stranger's heartbeat did not renew it
  scheduler_.Tick();
  EXPECT_EQ(scheduler_.counters().expired, 1u);
  const Lease b = MustLease("holder");
  EXPECT_TRUE(scheduler_.Extend(b.lease_id, "holder", 0.5).ok);
  EXPECT_EQ(
      scheduler_.Complete(b.lease_id, "stranger", SyntheticResult(b.task, cam.width, cam.height)).status,
      CompleteStatus::kNotHolder);
  EXPECT_EQ(CompleteOk(b).status, CompleteStatus::kMerged) << "the holder's lease is intact";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.counters().merged, 1u);
}

// The hostile farm (docs/farm.md, "Worker health"): a worker answering FailTask(retryable) in
// milliseconds took every retry of a task while the healthy worker was busy and failed the job.
// Now its failures count per worker: it is blocklisted for the job after 3, the task has failed on
// one worker only, and the healthy worker completes it.
TEST_F(SchedulerTest, OneFlakyWorkerIsBlocklistedAndAnotherWorkerFinishesTheJob) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  const Lease healthy = MustLease("healthy");  // busy with task 0 (heartbeats, does not poll)
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const Lease l = MustLease("flaky");
    ASSERT_EQ(l.task_id, 1u);
    ASSERT_EQ(l.attempt, attempt);
    EXPECT_EQ(scheduler_.Fail(l.lease_id, "flaky", "out of memory", /*retryable=*/true),
              FailOutcome::kFailed);
  }
  v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING) << s.failure_reason();
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "flaky");
  EXPECT_EQ(s.blocklisted_workers(0).failed_attempts(), 3u);
  EXPECT_THAT(s.blocklisted_workers(0).last_error(), HasSubstr("out of memory"));
  EXPECT_FALSE(scheduler_.TryLease({"flaky", {}}).has_value()) << "no more of this job for it";
  bool event = false;
  for (const v1::TaskEvent& e : scheduler_.activity().Events(id))
    event |= e.kind() == "blocklisted" && e.worker_id() == "flaky";
  EXPECT_TRUE(event) << "pf events shows it";
  for (const v1::WorkerInfo& w : scheduler_.activity().Workers())
    if (w.worker_id() == "flaky") {
      EXPECT_THAT(w.blocklisted_job_ids(), ::testing::ElementsAre(id));
    }

  EXPECT_EQ(CompleteOk(healthy).status, CompleteStatus::kMerged);
  const Lease retry = MustLease("healthy");
  EXPECT_EQ(retry.task_id, 1u);
  EXPECT_EQ(retry.attempt, 4u);
  EXPECT_EQ(CompleteOk(retry).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// A worker that leases and goes silent: each lease runs out with no call from it (lost), and
// after 3 it is blocklisted; the job survives with the second worker, which heartbeats.
TEST_F(SchedulerTest, SilentWorkerIsLostAndBlocklistedAndTheJobSurvivesWithASecondWorker) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  const Lease healthy = MustLease("healthy");
  auto lost = [&](const std::string& worker) {
    for (const v1::WorkerInfo& w : scheduler_.activity().Workers())
      if (w.worker_id() == worker) return w.lost();
    ADD_FAILURE() << worker << " not listed";
    return false;
  };
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const Lease l = MustLease("silent");
    ASSERT_EQ(l.task_id, 1u);
    EXPECT_FALSE(lost("silent")) << "it called: live";
    for (int beat = 0; beat < 3; ++beat) {  // the healthy worker heartbeats every lease/3
      clock_.Advance(10.5);
      EXPECT_TRUE(scheduler_.Extend(healthy.lease_id, "healthy", 0.5).ok);
      scheduler_.Tick();
    }
    EXPECT_TRUE(lost("silent")) << "its lease ran out with no call from it";
    EXPECT_FALSE(lost("healthy"));
  }
  EXPECT_EQ(scheduler_.counters().expired, 3u);
  v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING) << s.failure_reason();
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "silent");
  EXPECT_FALSE(scheduler_.TryLease({"silent", {}}).has_value());
  EXPECT_FALSE(lost("silent")) << "live again when it calls";
  EXPECT_EQ(CompleteOk(healthy).status, CompleteStatus::kMerged);
  EXPECT_EQ(CompleteOk(MustLease("healthy")).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// A worker that stops polling for 2 lease periods is lost; one whose long poll is open is not.
TEST_F(SchedulerTest, WorkerThatStopsPollingIsLostAndLiveAgainWhenItCalls) {
  std::vector<std::optional<Lease>> answers;
  EXPECT_FALSE(scheduler_.TryLease({"gone", {}}).has_value());
  scheduler_.LeaseOrWait({"waiting", {}}, 200,
                         [&](std::optional<Lease> l) { answers.push_back(std::move(l)); });
  auto lost = [&](const std::string& worker) {
    for (const v1::WorkerInfo& w : scheduler_.activity().Workers())
      if (w.worker_id() == worker) return w.lost();
    return false;
  };
  clock_.Advance(59);
  scheduler_.Tick();
  EXPECT_FALSE(lost("gone"));
  clock_.Advance(2);
  scheduler_.Tick();
  EXPECT_TRUE(lost("gone")) << "61 s without a call";
  EXPECT_FALSE(lost("waiting")) << "its long poll is open";
  EXPECT_FALSE(scheduler_.TryLease({"gone", {}}).has_value());
  EXPECT_FALSE(lost("gone"));
  EXPECT_TRUE(answers.empty());
}

// A worker that says it is leaving (LeaveFarm) is offline and never lost while it stays silent;
// one that just goes silent is lost; a call makes the leaver online again. An id that never
// polled is not listed by leaving.
TEST_F(SchedulerTest, AWorkerThatLeavesIsOfflineNotLostAndOnlineAgainWhenItCalls) {
  for (const char* worker : {"leaving", "silent"}) {
    scheduler_.activity().WorkerSeen(worker, "ipv4:10.0.0.1:1", 1, "v1");
    EXPECT_FALSE(scheduler_.TryLease({worker, {}}).has_value());
  }
  scheduler_.WorkerLeft("leaving");
  scheduler_.WorkerLeft("stranger");
  const auto info = [&](const std::string& worker) -> std::optional<v1::WorkerInfo> {
    for (const v1::WorkerInfo& w : scheduler_.activity().Workers())
      if (w.worker_id() == worker) return w;
    return std::nullopt;
  };
  clock_.Advance(600);
  scheduler_.Tick();
  ASSERT_TRUE(info("leaving").has_value());
  EXPECT_TRUE(info("leaving")->offline());
  EXPECT_FALSE(info("leaving")->lost()) << "it said it was leaving";
  EXPECT_TRUE(info("silent")->lost());
  EXPECT_FALSE(info("silent")->offline());
  EXPECT_FALSE(info("stranger").has_value());
  EXPECT_FALSE(scheduler_.TryLease({"leaving", {}}).has_value());
  EXPECT_FALSE(info("leaving")->offline()) << "online again when it calls";
  EXPECT_FALSE(info("leaving")->lost());
}

// A farm of one worker still fails a broken job after its attempts (no worker is left that may
// run it), with a reason naming the worker — it does not hang waiting for another worker.
TEST_F(SchedulerTest, OneWorkerFarmFailsABrokenJobAfterThreeAttemptsNamingTheWorker) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const Lease l = MustLease("only");
    ASSERT_EQ(l.task_id, 0u);
    EXPECT_EQ(scheduler_.Fail(l.lease_id, "only", "the scene crashes the renderer", true),
              FailOutcome::kFailed);
  }
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(),
              HasSubstr("task 0 attempt 3 failed: worker: the scene crashes the renderer"));
  EXPECT_THAT(s.failure_reason(),
              HasSubstr("no worker left to run the job: blocklisted for it: only after 3 failed attempts"));
  EXPECT_FALSE(scheduler_.TryLease({"only", {}}).has_value());
}

// A worker that left (LeaveFarm) is no worker that could still run a job: with the only other
// worker blocklisted, the broken job fails instead of waiting for the one that left.
TEST_F(SchedulerTest, AWorkerThatLeftDoesNotKeepABrokenJobWaiting) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  EXPECT_TRUE(scheduler_.TryLease({"restarted", {}}).has_value());  // a worker that then stopped
  scheduler_.WorkerLeft("restarted");
  for (uint32_t attempt = 1; attempt <= 3; ++attempt) {
    const Lease l = MustLease("only");
    EXPECT_EQ(scheduler_.Fail(l.lease_id, "only", "the scene crashes the renderer", true),
              FailOutcome::kFailed);
  }
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("no worker left to run the job"));
}

// A task fails its job after failures on max_attempts distinct workers.
TEST_F(SchedulerTest, ATaskFailsItsJobAfterFailuresOnThreeDistinctWorkers) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  for (const char* worker : {"w1", "w2", "w3"}) {
    const Lease l = MustLease(worker);
    EXPECT_EQ(scheduler_.Fail(l.lease_id, worker, "bad task", true), FailOutcome::kFailed);
  }
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("gave up after 3 failed attempts on 3 workers (w1, w2, w3)"));
  EXPECT_EQ(s.blocklisted_workers_size(), 0) << "one failure each";
}

// A retry goes first to another waiting worker, not back to the worker that failed it (which
// polls again at once); with nobody else waiting, it gets the retry itself.
TEST_F(SchedulerTest, ARetryGoesToAnotherWaitingWorkerFirst) {
  Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const Lease first = MustLease("w1");
  std::vector<std::pair<std::string, std::optional<Lease>>> answers;
  auto park = [&](const std::string& worker) {
    scheduler_.LeaseOrWait({worker, {}}, 10, [&, worker](std::optional<Lease> l) {
      answers.emplace_back(worker, std::move(l));
    });
  };
  park("w1");  // the oldest long poll: it would get the retry first
  park("w2");
  EXPECT_EQ(scheduler_.Fail(first.lease_id, "w1", "transient", true), FailOutcome::kFailed);
  ASSERT_EQ(answers.size(), 1u);
  EXPECT_EQ(answers[0].first, "w2");
  ASSERT_TRUE(answers[0].second.has_value());
  EXPECT_EQ(answers[0].second->attempt, 2u);
  // Alone, the worker that failed it gets it back.
  EXPECT_EQ(scheduler_.Fail(answers[0].second->lease_id, "w2", "transient", true), FailOutcome::kFailed);
  ASSERT_EQ(answers.size(), 2u);
  EXPECT_EQ(answers[1].first, "w1");
  ASSERT_TRUE(answers[1].second.has_value());
  EXPECT_EQ(answers[1].second->attempt, 3u);
}

// Blocklisted by 3 jobs within the window: no leases of any job for quarantine_seconds, shown in
// pf workers with the reason; then leases again.
TEST_F(SchedulerTest, AWorkerBlocklistedByThreeJobsIsQuarantined) {
  const std::string busy = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4, /*priority=*/9));
  const Lease healthy = MustLease("healthy");
  ASSERT_EQ(healthy.job_id, busy);
  std::vector<std::string> jobs;
  for (int j = 0; j < 3; ++j) jobs.push_back(Submit(MakeConfig(MultipleMaps(1, 0), 4, 4)));
  for (const std::string& job : jobs)
    for (int i = 0; i < 3; ++i) {
      const Lease l = MustLease("broken");
      ASSERT_EQ(l.job_id, job);
      EXPECT_EQ(scheduler_.Fail(l.lease_id, "broken", "GPU driver missing", true), FailOutcome::kFailed);
    }
  for (const std::string& job : jobs) EXPECT_EQ(scheduler_.Status(job).state(), v1::JOB_STATE_RUNNING);
  const std::string fresh = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4, /*priority=*/5));
  EXPECT_FALSE(scheduler_.TryLease({"broken", {}}).has_value()) << "quarantined: not even a fresh job";
  bool shown = false;
  for (const v1::WorkerInfo& w : scheduler_.activity().Workers())
    if (w.worker_id() == "broken") {
      shown = w.quarantined();
      EXPECT_THAT(w.quarantine_reason(), HasSubstr("blocklisted by 3 jobs within 900 s (" + jobs[0]));
      EXPECT_NEAR(w.quarantine_seconds_left(), 900, 1e-6);
      EXPECT_EQ(w.blocklisted_job_ids_size(), 3);
    }
  EXPECT_TRUE(shown);
  bool event = false;
  for (const v1::TaskEvent& e : scheduler_.activity().Events(jobs[2])) event |= e.kind() == "quarantined";
  EXPECT_TRUE(event);
  clock_.Advance(901);
  const std::optional<Lease> after = scheduler_.TryLease({"broken", {}});
  ASSERT_TRUE(after.has_value()) << "the quarantine is over";
  EXPECT_EQ(after->job_id, fresh);
  for (const v1::WorkerInfo& w : scheduler_.activity().Workers())
    if (w.worker_id() == "broken") {
      EXPECT_FALSE(w.quarantined());
    }
}

TEST_F(SchedulerTest, MaxRoundsSchedulesOnlyTheFirstRounds) {
  const std::string id = Submit(MakeConfig(Skipping(2, 5), 8, 8, 0, StopRule{.max_rounds = 2}));
  EXPECT_EQ(scheduler_.Status(id).tasks_total(), 8u);
  for (int i = 0; i < 8; ++i) {
    const Lease l = MustLease();
    EXPECT_LT(l.task.round, 2u);
    EXPECT_EQ(CompleteOk(l).status, CompleteStatus::kMerged);
  }
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.rounds_done(), 2u);
}

TEST_F(SchedulerTest, TimeBudgetStopsSchedulingAndSucceedsWithWhatWasMerged) {
  const std::string id =
      Submit(MakeConfig(MultipleMaps(10, 0), 4, 4, 0, StopRule{.time_budget_seconds = 50}));
  const Lease a = MustLease();
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  const Lease b = MustLease();
  clock_.Advance(25);
  EXPECT_TRUE(scheduler_.Extend(b.lease_id, b.worker_id, 0.5).ok);
  clock_.Advance(25);
  scheduler_.Tick();
  EXPECT_FALSE(scheduler_.TryLease({"w2", {}}).has_value()) << "nothing new after the budget";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << "the leased task may finish";
  EXPECT_TRUE(scheduler_.Extend(b.lease_id, b.worker_id, 0.9).ok);
  EXPECT_EQ(CompleteOk(b).status, CompleteStatus::kMerged);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), 2u);
  EXPECT_EQ(s.samples_merged(), 2u * 16);
}

TEST_F(SchedulerTest, TimeBudgetWithAnExpiringLeaseStillSucceeds) {
  const std::string id = Submit(MakeConfig(MultipleMaps(3, 0), 4, 4, 0, StopRule{.time_budget_seconds = 10}));
  EXPECT_EQ(CompleteOk(MustLease()).status, CompleteStatus::kMerged);
  MustLease();  // never comes back
  clock_.Advance(40);
  scheduler_.Tick();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 1u);
}

TEST_F(SchedulerTest, TargetNoiseEndsTheJobAfterTwoFullRounds) {
  // S = 2: 4 tasks per round; the noise is only judged once every pixel has two maps.
  const std::string id = Submit(MakeConfig(Skipping(2, 10), 8, 8, 0, StopRule{.target_noise_rms = 10.0}));
  for (int i = 0; i < 7; ++i) {
    EXPECT_EQ(CompleteOk(MustLease()).status, CompleteStatus::kMerged);
    EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << i;
  }
  const Lease last_of_round2 = MustLease();
  EXPECT_EQ(last_of_round2.task_id, 7u);
  EXPECT_EQ(CompleteOk(last_of_round2).status, CompleteStatus::kMerged);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), 8u);
  EXPECT_GE(s.estimated_noise_rms(), 0.0);
  EXPECT_LE(s.estimated_noise_rms(), 10.0);
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value()) << "remaining rounds cancelled";
}

TEST_F(SchedulerTest, UnreachableTargetNoiseRunsEveryRound) {
  const std::string id = Submit(MakeConfig(Skipping(1, 4), 4, 4, 0, StopRule{.target_noise_rms = 1e-9}));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(CompleteOk(MustLease()).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id).rounds_done(), 4u);
}

TEST_F(SchedulerTest, CancelStopsEverythingAndIsIdempotent) {
  const std::string id = Submit(MakeConfig(MultipleMaps(3, 0), 4, 4));
  const Lease a = MustLease();
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  const Lease b = MustLease();
  EXPECT_EQ(scheduler_.Cancel(id).state(), v1::JOB_STATE_CANCELLED);
  EXPECT_FALSE(scheduler_.Extend(b.lease_id, b.worker_id, 0).ok);
  EXPECT_EQ(CompleteOk(b).status, CompleteStatus::kIgnored);
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value());
  EXPECT_EQ(scheduler_.Cancel(id).state(), v1::JOB_STATE_CANCELLED);
  // The merged image so far stays available.
  const JobSnapshot snap = scheduler_.Snapshot(id, true);
  ASSERT_TRUE(snap.image.has_value());
  EXPECT_EQ(snap.image->samples_merged, 16u);
  EXPECT_THROW(scheduler_.Cancel("job-999"), NotFoundError);
  EXPECT_THROW(scheduler_.Status("nope"), NotFoundError);
}

TEST_F(SchedulerTest, EtaBeforeARateIsKnown) {
  // Two tasks (one map each), two workers: both running, so no warm rate can be measured before
  // the end, and the average rate with heartbeat progress is the estimate.
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  EXPECT_LT(scheduler_.Status(id).eta_seconds(), 0) << "unknown before any progress";
  const Lease a = MustLease("w1");
  const Lease b = MustLease("w2");
  clock_.Advance(10);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  // 1 of 2 tasks in 10 s, the other running: 10 s to go.
  EXPECT_NEAR(scheduler_.Status(id).eta_seconds(), 10.0, 1e-9);
  EXPECT_NEAR(scheduler_.Status(id).elapsed_seconds(), 10.0, 1e-9);
  EXPECT_TRUE(scheduler_.Extend(b.lease_id, b.worker_id, 0.5).ok);
  EXPECT_NEAR(scheduler_.Status(id).eta_seconds(), 10.0 * 0.5 / 1.5, 1e-9);

  // Four tasks on one worker: after the first, the rate would include the worker's start-up
  // (map building), so the ETA stays unknown until a second result gives a warm rate.
  const std::string four = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4));
  EXPECT_EQ(CompleteOk(b).status, CompleteStatus::kMerged);
  const Lease c = MustLease("w1");
  clock_.Advance(3);
  EXPECT_EQ(CompleteOk(c).status, CompleteStatus::kMerged);
  EXPECT_LT(scheduler_.Status(four).eta_seconds(), 0);
  const Lease d = MustLease("w1");
  clock_.Advance(1);
  EXPECT_EQ(CompleteOk(d).status, CompleteStatus::kMerged);
  EXPECT_NEAR(scheduler_.Status(four).eta_seconds(), 2.0, 1e-9) << "2 tasks left at 1 per s";
}

// The default farm job's shape: one worker builds its map once (1.2 s here), then renders tiles
// of 0.5 s each. The average-rate formula counted that start-up in every tile (it said 11.7 s
// after three tiles where 6.5 s remained); the throughput window must not.
TEST_F(SchedulerTest, EtaIsNotInflatedByAWorkersStartUp) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 4), 16, 16));  // 16 tiles of 4×4
  ASSERT_EQ(scheduler_.Status(id).tasks_total(), 16u);
  constexpr double kStartUp = 1.2, kTile = 0.5;
  for (int done = 1; done <= 15; ++done) {
    const Lease lease = MustLease();
    if (done >= 3) {
      // Half way through this tile: the work since the last completion is credited.
      clock_.Advance(kTile / 2);
      const double truth = (16 - (done - 1)) * kTile - kTile / 2;
      EXPECT_NEAR(scheduler_.Status(id).eta_seconds(), truth, 0.05 * truth) << done - 1 << " tiles + ½";
      clock_.Advance(kTile / 2);
    } else {
      clock_.Advance(kTile + (done == 1 ? kStartUp : 0.0));
    }
    ASSERT_EQ(CompleteOk(lease).status, CompleteStatus::kMerged);
    if (done < 2) continue;  // one completion: no rate yet (the fallback)
    const double truth = (16 - done) * kTile;
    EXPECT_NEAR(scheduler_.Status(id).eta_seconds(), truth, 0.05 * truth + 1e-9) << done << " tiles done";
  }
}

TEST_F(SchedulerTest, EtaGrowsWhenTheNextResultIsOverdue) {
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 4), 16, 16));
  for (int done = 0; done < 4; ++done) {
    const Lease lease = MustLease();
    clock_.Advance(1.0);
    ASSERT_EQ(CompleteOk(lease).status, CompleteStatus::kMerged);
  }
  const Lease stuck = MustLease();
  const double on_time = scheduler_.Status(id).eta_seconds();
  EXPECT_NEAR(on_time, 12.0, 1e-6);
  clock_.Advance(5.0);  // the tile that takes 1 s has taken 5 s
  const double overdue = scheduler_.Status(id).eta_seconds();
  EXPECT_GT(overdue, on_time) << "a stalled farm must not show a shrinking ETA";
  // Completions at 1, 2, 3, 4 s; now 9 s: were one to come now, 4 in the 8 s since the first, so
  // the rate is at most 0.5 per s; the running tile is credited as done: (12 − 1) / 0.5.
  EXPECT_NEAR(overdue, 11.0 / 0.5, 1e-6);
  (void)stuck;
}

TEST_F(SchedulerTest, MergedImageDoesNotDependOnCompletionOrder) {
  FakeClock other_clock;
  Scheduler other(other_clock, SchedulerOptions{});
  const JobConfig config = MakeConfig(Skipping(3, 2), 9, 7);
  const std::string id = Submit(config);
  std::unique_ptr<Job> j = other.PrepareJob(config);
  const std::string other_id = j->id();
  other.AddJob(std::move(j));
  std::vector<Lease> leases, other_leases;
  for (int i = 0; i < 18; ++i) {
    leases.push_back(MustLease());
    other_leases.push_back(*other.TryLease({"w", {}}));
  }
  for (const Lease& l : leases) ASSERT_EQ(CompleteOk(l).status, CompleteStatus::kMerged);
  for (auto it = other_leases.rbegin(); it != other_leases.rend(); ++it)
    ASSERT_EQ(other.Complete(it->lease_id, it->worker_id, SyntheticResult(it->task, 9, 7)).status,
              CompleteStatus::kMerged);
  const JobSnapshot a = scheduler_.Snapshot(id, true), b = other.Snapshot(other_id, true);
  ASSERT_TRUE(a.image && b.image);
  ASSERT_EQ(a.image->image.size(), b.image->image.size());
  for (size_t p = 0; p < a.image->image.size(); ++p)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(a.image->image[p][c], b.image->image[p][c]) << p;
  // The EXR bytes too, apart from the job id in the metadata (ids are random).
  ResolvedImage b_as_a = *b.image;
  b_as_a.metadata["job_id"] = a.image->metadata.at("job_id");
  EXPECT_EQ(EncodeSnapshot(*a.image), EncodeSnapshot(b_as_a));
}

TEST_F(SchedulerTest, PersistenceHandsOutChangedRowsAndCheckpoints) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 4, 4));
  EXPECT_TRUE(scheduler_.CollectCheckpoints(true).empty());
  const Lease a = MustLease();
  RowBatch rows = scheduler_.CollectRows();
  ASSERT_EQ(rows.tasks.size(), 1u);
  EXPECT_EQ(rows.tasks[0].state, TaskState::kLeased);
  EXPECT_EQ(rows.tasks[0].attempts, 1u);
  ASSERT_EQ(rows.jobs.size(), 1u);
  EXPECT_EQ(rows.jobs[0].state, JobState::kRunning);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  EXPECT_TRUE(scheduler_.CollectCheckpoints(/*due=*/false).empty()) << "not due yet";
  EXPECT_TRUE(scheduler_.CollectRows().tasks.empty()) << "a DONE row waits until its result is stored";
  EXPECT_TRUE(scheduler_.HasUncheckpointedMerges());
  const uint64_t journaled[] = {a.task_id};
  scheduler_.ResultsJournaled(id, journaled);
  rows = scheduler_.CollectRows();
  ASSERT_EQ(rows.tasks.size(), 1u);
  EXPECT_EQ(rows.tasks[0].state, TaskState::kDone);
  std::vector<Checkpoint> cps = scheduler_.CollectCheckpoints(true);
  ASSERT_EQ(cps.size(), 1u);
  EXPECT_EQ(cps[0].job_id, id);
  EXPECT_EQ(cps[0].merged_task_ids, std::vector<uint64_t>{a.task_id});
  EXPECT_EQ(cps[0].merge_seq, 1u);
  EXPECT_FALSE(scheduler_.HasUncheckpointedMerges());
  // A finished job is checkpointed even when checkpoints are not due; its final row and its last
  // DONE row wait until that checkpoint is stored, and the row carries the checkpoint's seal.
  EXPECT_EQ(CompleteOk(MustLease()).status, CompleteStatus::kMerged);
  cps = scheduler_.CollectCheckpoints(false);
  ASSERT_EQ(cps.size(), 1u);
  EXPECT_EQ(cps[0].merged_task_ids.size(), 2u);
  rows = scheduler_.CollectRows();
  EXPECT_TRUE(rows.jobs.empty()) << "the final row waits for the final checkpoint";
  EXPECT_TRUE(rows.tasks.empty());
  scheduler_.CheckpointNotStored(id, cps[0].merge_seq, "No space left on device");
  EXPECT_THAT(scheduler_.Status(id).storage_error(), HasSubstr("No space left on device"));
  EXPECT_TRUE(scheduler_.CollectRows().jobs.empty()) << "still not stored";
  cps = scheduler_.CollectCheckpoints(false);
  ASSERT_EQ(cps.size(), 1u) << "a failed checkpoint is collected again at the next flush";
  const CheckpointSeal seal{2, 0x1234};
  scheduler_.CheckpointStored(cps[0], seal, "/x.acc");
  rows = scheduler_.CollectRows();
  ASSERT_EQ(rows.jobs.size(), 1u);
  EXPECT_EQ(rows.jobs[0].state, JobState::kSucceeded);
  EXPECT_EQ(rows.jobs[0].checkpoint, seal);
  ASSERT_EQ(rows.tasks.size(), 1u);
  EXPECT_EQ(rows.tasks[0].state, TaskState::kDone);
  EXPECT_EQ(scheduler_.Status(id).storage_error(), "");
}

TEST_F(SchedulerTest, AJobWhoseResultsCannotBeStoredGetsNoLeasesUntilACheckpointIsStored) {
  const std::string paused = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4));
  const Lease a = MustLease();
  ASSERT_EQ(a.job_id, paused);
  EXPECT_EQ(CompleteOk(a).status, CompleteStatus::kMerged);
  scheduler_.ResultsNotStored(paused, "journal write: No space left on device");
  const v1::JobStatus status = scheduler_.Status(paused);
  EXPECT_TRUE(status.paused_for_storage());
  EXPECT_THAT(status.storage_error(), HasSubstr("No space left on device"));
  EXPECT_FALSE(scheduler_.TryLease({"w", {}}).has_value()) << "its queued tasks are held back";
  const std::string other = Submit(MakeConfig(MultipleMaps(1, 0), 4, 4));
  const std::optional<Lease> b = scheduler_.TryLease({"w", {}});
  ASSERT_TRUE(b.has_value()) << "other jobs are served";
  EXPECT_EQ(b->job_id, other);
  const std::vector<Checkpoint> cps = scheduler_.CollectCheckpoints(/*due=*/false);
  ASSERT_EQ(cps.size(), 1u) << "the paused job's checkpoint is tried at the next flush";
  scheduler_.CheckpointStored(cps[0], CheckpointSeal{1, 7}, "/p.acc");
  EXPECT_FALSE(scheduler_.Status(paused).paused_for_storage());
  const std::optional<Lease> c = scheduler_.TryLease({"w", {}});
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->job_id, paused) << "resumed";
}

TEST(JobStateMachine, OnlyForwardTransitions) {
  EXPECT_TRUE(Job::CanTransition(JobState::kQueued, JobState::kRunning));
  EXPECT_TRUE(Job::CanTransition(JobState::kQueued, JobState::kCancelled));
  EXPECT_TRUE(Job::CanTransition(JobState::kRunning, JobState::kSucceeded));
  EXPECT_TRUE(Job::CanTransition(JobState::kRunning, JobState::kFailed));
  EXPECT_FALSE(Job::CanTransition(JobState::kQueued, JobState::kSucceeded));
  EXPECT_FALSE(Job::CanTransition(JobState::kRunning, JobState::kQueued));
  EXPECT_FALSE(Job::CanTransition(JobState::kSucceeded, JobState::kRunning));
  EXPECT_FALSE(Job::CanTransition(JobState::kCancelled, JobState::kFailed));
  EXPECT_FALSE(Job::CanTransition(JobState::kFailed, JobState::kFailed));
}

}  // namespace
}  // namespace pf::server

namespace pf::server {
namespace {

// A dynamic plan in miniature: each merged task of map m < 3 creates the same tile with map
// m + 1 — a pure function of which tasks are merged, as task_source.h requires.
class ChainSource : public TaskSource {
 public:
  std::vector<TaskSpec> TasksAfterMerge(const Job& job) override {
    std::vector<TaskSpec> added;
    uint64_t next = job.num_tasks();
    for (uint64_t id = 0; id < job.num_tasks(); ++id) {
      const TaskSpec& t = job.task(id);
      if (job.runtime(id).state != TaskState::kDone || t.map_index >= 3 || created_.count(id)) continue;
      created_.insert(id);
      TaskSpec child = t;
      child.task_id = next++;
      child.map_index = t.map_index + 1;
      child.map_seed = MapSeed(job.config().seed, child.map_index);
      child.pixel_seed = PixelSeed(job.config().seed, child.map_index);
      added.push_back(child);
    }
    return added;
  }

 private:
  std::set<uint64_t> created_;
};

TEST(SchedulerTaskSource, TasksCreatedFromResultsAreQueuedAndTheJobEndsAfterThem) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{},
                      [](const JobConfig&) { return std::make_unique<ChainSource>(); });
  std::unique_ptr<Job> job = scheduler.PrepareJob(testing::MakeConfig(testing::MultipleMaps(1, 2), 4, 4));
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  EXPECT_EQ(scheduler.Status(id).tasks_total(), 4u) << "2×2 tiles of map 0";
  auto complete = [&](const Lease& lease) {
    const auto& cam = lease.config->camera;
    ASSERT_EQ(
        scheduler
            .Complete(lease.lease_id, lease.worker_id, SyntheticResult(lease.task, cam.width, cam.height))
            .status,
        CompleteStatus::kMerged);
  };
  // All four leased: nothing is queued, so a long poll parks — and is answered by the task that
  // the next merge creates.
  std::vector<Lease> first;
  for (int i = 0; i < 4; ++i) first.push_back(*scheduler.TryLease({"w", {}}));
  std::optional<Lease> waited;
  scheduler.LeaseOrWait({"poll", {}}, 10, [&](std::optional<Lease> l) { waited = std::move(l); });
  EXPECT_FALSE(waited.has_value());
  complete(first[0]);
  ASSERT_TRUE(waited.has_value());
  EXPECT_EQ(waited->task_id, 4u);
  EXPECT_EQ(waited->task.map_index, 1u);
  EXPECT_EQ(scheduler.Status(id).tasks_total(), 5u);
  complete(*waited);
  for (size_t i = 1; i < first.size(); ++i) complete(first[i]);
  std::vector<uint64_t> maps;
  while (std::optional<Lease> lease = scheduler.TryLease({"w", {}})) {
    maps.push_back(lease->task.map_index);
    EXPECT_EQ(scheduler.Status(id).state(), v1::JOB_STATE_RUNNING);
    complete(*lease);
  }
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_total(), 16u) << "4 tiles × maps 0..3";
  EXPECT_EQ(s.tasks_done(), 16u);
  EXPECT_EQ(s.samples_merged(), 4u * 16u);
  EXPECT_EQ(maps.size(), 11u);
}

TEST(SchedulerTaskSource, NoTasksAreCreatedAfterTheTimeBudget) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{},
                      [](const JobConfig&) { return std::make_unique<ChainSource>(); });
  std::unique_ptr<Job> job = scheduler.PrepareJob(
      testing::MakeConfig(testing::MultipleMaps(1, 0), 4, 4, 0, StopRule{.time_budget_seconds = 5}));
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  std::optional<Lease> lease = scheduler.TryLease({"w", {}});
  ASSERT_TRUE(lease.has_value());
  clock.Advance(6);
  scheduler.Tick();
  ASSERT_EQ(scheduler.Complete(lease->lease_id, lease->worker_id, SyntheticResult(lease->task, 4, 4)).status,
            CompleteStatus::kMerged);
  EXPECT_EQ(scheduler.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler.Status(id).tasks_done(), 1u);
  EXPECT_FALSE(scheduler.TryLease({"w", {}}).has_value());
}

}  // namespace
}  // namespace pf::server

namespace pf::server {
namespace {

PlanSpec SmallHierarchy() {
  return PlanSpec{.kind = PlanKind::kHierarchical,
                  .levels = 2,
                  .dims = 2,
                  .base_samples = 2,
                  .min_samples = 1,
                  .localize_threshold = 0.5,  // the synthetic results' noise localizes many pixels
                  .localize_contrast = 0};
}

// SmallHierarchy on the photon-map part only (--hier-part indirect), with 2 samples per pixel
// for the emission + direct light tasks.
PlanSpec SmallIndirectHierarchy() {
  PlanSpec plan = SmallHierarchy();
  plan.hierarchy_part = HierarchyPart::kIndirect;
  plan.direct_samples = 2;
  return plan;
}

// The hierarchical plan through the scheduler (its own task source): localization tasks appear
// after the levels complete, the job ends after them, and a snapshot shows the assembled image.
TEST(SchedulerTaskSource, HierarchicalJobCreatesLocalizationTasksFromItsResults) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{});
  std::unique_ptr<Job> job = scheduler.PrepareJob(testing::MakeConfig(SmallHierarchy(), 12, 10));
  const std::string id = job->id();
  const uint64_t static_tasks = job->num_tasks();
  scheduler.AddJob(std::move(job));
  EXPECT_EQ(scheduler.Status(id).tasks_total(), static_tasks);
  HierarchicalAssembly expected(SmallHierarchy(), 12, 10);
  while (std::optional<Lease> lease = scheduler.TryLease({"w", {}})) {
    const std::vector<float> sums = SyntheticResult(lease->task, 12, 10);
    expected.Add(lease->task, PixelsOf(lease->task.pixels, 12, 10), sums, 1);
    ASSERT_EQ(scheduler.Complete(lease->lease_id, lease->worker_id, sums).status, CompleteStatus::kMerged);
  }
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_GT(s.tasks_total(), static_tasks);
  EXPECT_EQ(s.tasks_done(), s.tasks_total());
  const JobSnapshot snap = scheduler.Snapshot(id, true);
  ASSERT_TRUE(snap.image.has_value());
  const Image want = expected.Resolve();
  for (size_t p = 0; p < want.size(); ++p) ASSERT_TRUE(snap.image->image[p] == want[p]) << p;
}

// A "render" with what the hierarchy is for: a step (x < 0.37 W: 0.2, else 1) that localization
// must catch, a smooth per-map error (the photon map's low-frequency noise) and a little
// per-pixel noise.
std::vector<float> StepImageResult(const TaskSpec& task, int width, int height) {
  const std::vector<uint32_t> pixels = PixelsOf(task.pixels, width, height);
  std::vector<float> sums(pixels.size() * 3);
  const uint32_t samples = task.sample_end - task.sample_begin;
  Rng map_rng = Rng::ForKey(HashKey(task.map_seed, 5));
  const double map_error = 0.1 * (map_rng.Uniform() - 0.5);
  for (size_t i = 0; i < pixels.size(); ++i) {
    const double x = double(pixels[i] % uint32_t(width)) / width,
                 y = double(pixels[i] / uint32_t(width)) / height;
    Rng rng = Rng::ForKey(HashKey(task.map_seed, pixels[i], 99));
    const double v = (x < 0.37 ? 0.2 : 1.0) + map_error * (1 + x * y) + 0.01 * (rng.Uniform() - 0.5);
    for (int c = 0; c < 3; ++c) sums[3 * i + c] = float(samples * v);
  }
  return sums;
}

// Progress and ETA of a hierarchical job, whose tasks differ in cost (a level-0 task
// renders a few points, a last-level task a quarter of the image) and whose localization tasks
// appear only when every level is complete. One simulated worker runs the tasks in queue order; a
// task takes c_px × its pixel samples + c_map, with c_map 2.5× what the coordinator assumes
// (kMapWorkPerPhoton), so the work model is off. After every merge: the progress never goes
// down, and from 10 % to 95 % of the job's time the ETA is within a factor of 2 of the true
// remaining time. (Counting tasks, the progress fell when the localization tasks appeared and the
// ETA fell to 0.44× the truth; measured now: 0.76-1.27×.)
TEST(SchedulerEta, HierarchicalProgressIsMonotoneAndItsEtaWithinTwiceTheTruth) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{.lease_seconds = 1e6});
  const int w = 129, h = 129;
  JobConfig config = MakeConfig(PlanSpec{.kind = PlanKind::kHierarchical,
                                         .tile_size = 32,
                                         .levels = 7,
                                         .dims = 2,
                                         .base_samples = 16,
                                         .min_samples = 2,
                                         .decay = 1.5},
                                w, h);
  config.settings.photons = 10000;
  std::unique_ptr<Job> job = scheduler.PrepareJob(config);
  const std::string id = job->id();
  const uint64_t static_tasks = job->num_tasks();
  scheduler.AddJob(std::move(job));
  const double c_px = 1e-6, c_map = 2.5 * double(MapWork(config.settings.photons)) * c_px;
  struct Point {
    double time, eta, progress;
  };
  std::vector<Point> points;
  const double start = clock.Now();
  while (std::optional<Lease> lease = scheduler.TryLease({"w", {}})) {
    const uint64_t pixels = PixelsOf(lease->task.pixels, w, h).size();
    clock.Advance(c_map + c_px * double(pixels * (lease->task.sample_end - lease->task.sample_begin)));
    ASSERT_EQ(
        scheduler.Complete(lease->lease_id, lease->worker_id, StepImageResult(lease->task, w, h)).status,
        CompleteStatus::kMerged);
    const v1::JobStatus s = scheduler.Status(id);
    points.push_back({clock.Now(), s.eta_seconds(), s.progress()});
  }
  const v1::JobStatus final_status = scheduler.Status(id);
  ASSERT_EQ(final_status.state(), v1::JOB_STATE_SUCCEEDED);
  ASSERT_GT(final_status.tasks_total(), static_tasks + 8) << "localization tasks were created";
  EXPECT_EQ(final_status.progress(), 1.0);
  const double end = points.back().time, span = end - start;
  double previous = 0;
  size_t checked = 0;
  for (const Point& p : points) {
    const double t = p.time - start;
    EXPECT_GE(p.progress, previous - 1e-12) << "at t = " << t << " of " << span;
    previous = p.progress;
    if (t < 0.1 * span || t > 0.95 * span) continue;
    ++checked;
    const double truth = end - p.time;
    EXPECT_GE(p.eta, 0.5 * truth) << "at t = " << t << " of " << span;
    EXPECT_LE(p.eta, 2.0 * truth) << "at t = " << t << " of " << span;
  }
  EXPECT_GT(checked, 100u);
}

// Tail tiles: the default farm job's 12 tiles of 64² and 16 tail tiles of 32². Its
// progress counts pixel samples, not tasks: with the 12 whole tiles merged, 3/4 of the pixels are
// done (counting tasks it read 12/28 = 43 %), and each tail tile adds 1/64.
TEST(SchedulerEta, TailTilesCountTheirPixels) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{.lease_seconds = 1e6});
  const int w = 256, h = 256;
  std::unique_ptr<Job> job = scheduler.PrepareJob(MakeConfig(
      PlanSpec{
          .kind = PlanKind::kMultipleMaps, .samples_per_pixel = 2, .tile_size = 64, .tail_tile_size = 32},
      w, h));
  const std::string id = job->id();
  ASSERT_EQ(job->num_tasks(), 28u);
  scheduler.AddJob(std::move(job));
  for (int i = 0; i < 13; ++i) {
    std::optional<Lease> lease = scheduler.TryLease({"w", {}});
    ASSERT_TRUE(lease.has_value());
    ASSERT_EQ(lease->task.task_id, uint64_t(i)) << "tasks are leased in id order: the tail tiles last";
    ASSERT_EQ(
        scheduler.Complete(lease->lease_id, lease->worker_id, SyntheticResult(lease->task, w, h)).status,
        CompleteStatus::kMerged);
    if (i == 11) {
      EXPECT_DOUBLE_EQ(scheduler.Status(id).progress(), 0.75);
    }
  }
  EXPECT_DOUBLE_EQ(scheduler.Status(id).progress(), 0.75 + 1.0 / 64);
}

// --hier-part indirect: a result must be of the task's radiance part (CompleteTaskRequest.part).
// A worker older than Task.part renders the whole radiance and echoes nothing (part all): its
// result for an emission + direct light task is rejected and the task re-queued, never merged
// (merged, it would add emission and direct light twice); the right part then merges.
TEST(SchedulerTaskSource, AResultOfAnotherRadiancePartIsRejected) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{});
  const PlanSpec plan = SmallIndirectHierarchy();
  std::unique_ptr<Job> job = scheduler.PrepareJob(testing::MakeConfig(plan, 12, 10));
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  std::optional<Lease> lease = scheduler.TryLease({"w", {}});
  ASSERT_TRUE(lease.has_value());
  ASSERT_EQ(lease->task.part, RadiancePart::kUnmapped) << "the per-pixel tasks come first";
  const CompleteResult old_worker = scheduler.Complete(
      lease->lease_id, lease->worker_id, SyntheticResult(lease->task, 12, 10), RadiancePart::kAll);
  EXPECT_EQ(old_worker.status, CompleteStatus::kRejected);
  EXPECT_NE(old_worker.reason.find("part"), std::string::npos) << old_worker.reason;
  EXPECT_EQ(scheduler.Status(id).tasks_done(), 0u);
  std::optional<Lease> again = scheduler.TryLease({"w", {}});
  ASSERT_TRUE(again.has_value());
  ASSERT_EQ(again->task.task_id, lease->task.task_id) << "re-queued";
  EXPECT_EQ(scheduler
                .Complete(again->lease_id, again->worker_id, SyntheticResult(again->task, 12, 10),
                          RadiancePart::kUnmapped)
                .status,
            CompleteStatus::kMerged);
  EXPECT_EQ(scheduler.Status(id).tasks_done(), 1u);
}

// --hier-part indirect under a time budget: when it is reached, the levels' queued tasks are
// cancelled but the emission + direct light tasks are not (the only ones of their pixels: without
// them the image would miss its light sources there); the job ends once they are merged.
TEST(SchedulerTaskSource, TimeBudgetKeepsTheEmissionAndDirectLightTasks) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{});
  const PlanSpec plan = SmallIndirectHierarchy();
  std::unique_ptr<Job> job =
      scheduler.PrepareJob(testing::MakeConfig(plan, 12, 10, 0, StopRule{.time_budget_seconds = 5}));
  const std::string id = job->id();
  uint64_t unmapped = 0;
  for (uint64_t t = 0; t < job->num_tasks(); ++t) unmapped += job->task(t).part == RadiancePart::kUnmapped;
  ASSERT_GT(unmapped, 0u);
  ASSERT_LT(unmapped, job->num_tasks());
  scheduler.AddJob(std::move(job));
  // The budget counts from the job's start (its first lease): one emission + direct light task.
  std::optional<Lease> first = scheduler.TryLease({"w", {}});
  ASSERT_TRUE(first.has_value());
  ASSERT_EQ(first->task.part, RadiancePart::kUnmapped);
  ASSERT_EQ(
      scheduler
          .Complete(first->lease_id, first->worker_id, SyntheticResult(first->task, 12, 10), first->task.part)
          .status,
      CompleteStatus::kMerged);
  clock.Advance(6);
  scheduler.Tick();
  uint64_t leased = 1;
  while (std::optional<Lease> lease = scheduler.TryLease({"w", {}})) {
    EXPECT_EQ(lease->task.part, RadiancePart::kUnmapped);
    ASSERT_EQ(scheduler
                  .Complete(lease->lease_id, lease->worker_id, SyntheticResult(lease->task, 12, 10),
                            lease->task.part)
                  .status,
              CompleteStatus::kMerged);
    ++leased;
  }
  EXPECT_EQ(leased, unmapped);
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), unmapped);
}

TEST(SchedulerTaskSource, TimeBudgetStopsAHierarchicalJobBeforeItsLocalization) {
  FakeClock clock;
  Scheduler scheduler(clock, SchedulerOptions{});
  std::unique_ptr<Job> job = scheduler.PrepareJob(
      testing::MakeConfig(SmallHierarchy(), 12, 10, 0, StopRule{.time_budget_seconds = 5}));
  const std::string id = job->id();
  const uint64_t static_tasks = job->num_tasks();
  scheduler.AddJob(std::move(job));
  std::vector<Lease> leases;
  while (std::optional<Lease> lease = scheduler.TryLease({"w", {}})) leases.push_back(*lease);
  ASSERT_EQ(leases.size(), static_tasks);
  clock.Advance(6);
  scheduler.Tick();
  for (const Lease& l : leases)
    ASSERT_EQ(scheduler.Complete(l.lease_id, l.worker_id, SyntheticResult(l.task, 12, 10)).status,
              CompleteStatus::kMerged);
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_total(), static_tasks) << "no localization after the budget";
  EXPECT_FALSE(scheduler.TryLease({"w", {}}).has_value());
}

}  // namespace
}  // namespace pf::server

namespace pf::server {
namespace {

// Render tasks whose map is not ready are held out of the queue (the map's pieces, in the
// Scheduler's one queue, are leased first, parked long polls get them), and a released map
// (MapUpdate::release) queues them; a hook that says "ready" changes nothing.
class FakeMapHook final : public MapTracingHook {
 public:
  bool RenderTaskReady(const Job& /*job*/, const TaskSpec& task, MapUpdate& update) override {
    update.maps.insert("key");  // its pieces join the queue (idempotent)
    return ready.count(task.map_index) > 0;
  }
  QueuedPieces QueuedPiecesOf(const std::string& /*map_key*/) override {
    return {1, std::vector<uint32_t>(queued.begin(), queued.end())};
  }
  std::optional<Lease> LeasePiece(const TaskQueue::Piece& piece, const std::string& /*worker_id*/,
                                  const IssuePieceLease& issue) override {
    if (throw_on_lease) throw std::runtime_error("no lease id");  // before the piece changes
    if (!queued.erase(piece.index)) return std::nullopt;
    Lease l;
    l.lease_id = issue("job", piece.map_key, piece.index, 1);
    l.chunk = TraceChunkLease{piece.map_key, 0, 4096, piece.index, 8};
    return l;
  }
  bool PieceLeaseCurrent(const std::string&, uint32_t, const std::string&) override { return true; }
  std::vector<std::string> JobsOfMap(const std::string&) override { return {}; }
  MapUpdate PieceReturned(const std::string&, uint32_t, const std::string&) override { return {}; }
  MapUpdate PieceLeaseEnded(const PieceLeaseEnd& end) override {
    ended.push_back(end.lease_id);
    if (throw_on_end) throw std::runtime_error("bookkeeping failed");
    return {};
  }
  std::set<uint64_t> ready;
  std::set<uint32_t> queued;  // the map's queued pieces
  bool throw_on_end = false, throw_on_lease = false;
  std::vector<std::string> ended;
};

// A piece whose lease could not be made stays queued in the one queue (it is still queued in its
// map), and is leased once leasing works again.
TEST_F(SchedulerTest, APieceWhoseLeaseFailsStaysQueued) {
  FakeMapHook hook;
  hook.queued = {0};
  hook.throw_on_lease = true;
  scheduler_.SetMapTracingHook(&hook);
  Submit(MakeConfig(MultipleMaps(1, 2), 4, 4));
  EXPECT_THROW(scheduler_.TryLease({"w1", {}}), std::runtime_error);
  hook.throw_on_lease = false;
  const Lease piece = MustLease("w1");
  ASSERT_TRUE(piece.chunk.has_value()) << "the piece left the queue when its lease failed";
  EXPECT_EQ(piece.chunk->chunk_index, 0u);
  scheduler_.SetMapTracingHook(nullptr);
}

// A piece's lease ends in the scheduler's table and reaches its map in the same hold of the lock:
// one end whose bookkeeping throws must not keep the others from their maps (they would stay
// leased for ever), nor fail the tick.
TEST_F(SchedulerTest, AnExpiredPieceTheMapDidNotRecordIsEndedAgain) {
  FakeMapHook hook;
  hook.queued = {0, 1};
  hook.throw_on_end = true;
  scheduler_.SetMapTracingHook(&hook);
  Submit(MakeConfig(MultipleMaps(1, 2), 4, 4));
  const Lease a = MustLease("w1");
  const Lease b = MustLease("w2");
  ASSERT_TRUE(a.chunk.has_value() && b.chunk.has_value());
  EXPECT_EQ(a.chunk->chunk_index, 0u) << "lowest piece first";
  EXPECT_EQ(b.chunk->chunk_index, 1u);
  clock_.Advance(31);
  EXPECT_NO_THROW(scheduler_.Tick());
  std::sort(hook.ended.begin(), hook.ended.end());
  std::vector<std::string> leased{a.lease_id, b.lease_id};
  std::sort(leased.begin(), leased.end());
  EXPECT_EQ(hook.ended, leased);
  // Not recorded by the map: the leases stay, and the next tick ends them again; once recorded
  // they are gone (no third end).
  hook.throw_on_end = false;
  hook.ended.clear();
  scheduler_.Tick();
  std::sort(hook.ended.begin(), hook.ended.end());
  EXPECT_EQ(hook.ended, leased) << "an end the map did not record is tried again";
  hook.ended.clear();
  scheduler_.Tick();
  EXPECT_TRUE(hook.ended.empty()) << "a recorded end is not repeated";
  scheduler_.SetMapTracingHook(nullptr);
}

TEST_F(SchedulerTest, RenderTasksWaitForTheirMapAndPiecesComeFirst) {
  FakeMapHook hook;
  hook.queued = {0};
  hook.ready = {1};
  scheduler_.SetMapTracingHook(&hook);
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 2), 4, 4));  // 2 maps x 4 tiles
  const Lease piece = MustLease();
  ASSERT_TRUE(piece.chunk.has_value()) << "pieces are served before render tasks";
  for (int i = 0; i < 4; ++i) {
    const Lease l = MustLease();
    EXPECT_FALSE(l.chunk.has_value());
    EXPECT_EQ(l.task.map_index, 1u) << "map 0 is not built yet";
  }
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value());
  EXPECT_EQ(scheduler_.Status(id).tasks_queued(), 4u) << "held tasks still count as queued";
  // A parked long poll is served when a piece appears, then when the map is released.
  std::optional<Lease> parked;
  bool answered = false;
  scheduler_.LeaseOrWait({"w2", {}}, 10, [&](std::optional<Lease> l) {
    parked = std::move(l);
    answered = true;
  });
  EXPECT_FALSE(answered);
  hook.queued = {3};
  scheduler_.ApplyMapUpdate(MapUpdate{.maps = {"key"}});
  ASSERT_TRUE(answered);
  ASSERT_TRUE(parked.has_value() && parked->chunk.has_value());
  EXPECT_EQ(parked->chunk->chunk_index, 3u);
  hook.ready.insert(0);
  scheduler_.ApplyMapUpdate(MapUpdate{.release = {{id, 0}}});
  for (int i = 0; i < 4; ++i) EXPECT_EQ(MustLease().task.map_index, 0u);
  scheduler_.ApplyMapUpdate(MapUpdate{.release = {{id, 0}}});  // twice: nothing more
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value());
  scheduler_.SetMapTracingHook(nullptr);
}

}  // namespace
}  // namespace pf::server

namespace pf::server {
namespace {

// A convicted worker's results are in the job's image: the job starts again from nothing without
// it, leases nothing until the empty image is stored, and ends in the image of an honest run.
TEST_F(SchedulerTest, AConvictedWorkersJobStartsAgainWithoutItAndEndsInTheHonestImage) {
  const JobConfig config = MakeConfig(MultipleMaps(6, 0), 8, 4);
  const std::string reference = Submit(config);
  while (std::optional<Lease> l = scheduler_.TryLease({"honest", {}})) CompleteOk(*l);
  const std::string id = Submit(config);
  const Lease liar = MustLease("liar");
  const auto& cam = liar.config->camera;
  std::vector<float> wrong = SyntheticResult(liar.task, cam.width, cam.height);
  for (float& v : wrong) v *= 1.5f;
  ASSERT_EQ(scheduler_.Complete(liar.lease_id, liar.worker_id, wrong).status, CompleteStatus::kMerged);
  EXPECT_EQ(CompleteOk(MustLease("honest")).status, CompleteStatus::kMerged);
  const Lease in_flight = MustLease("honest");
  uint64_t old_seq = 0;
  for (const Checkpoint& cp : scheduler_.CollectCheckpoints(true))
    if (cp.job_id == id) old_seq = cp.merge_seq;
  ASSERT_EQ(old_seq, 2u);
  ASSERT_EQ(scheduler_.JobEpoch(id), 0u);

  ASSERT_TRUE(scheduler_.ConvictWorker(id, "liar", liar.task_id, "result differs from another render"));
  v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.tasks_done(), 0u);
  EXPECT_EQ(s.tasks_queued(), 6u);
  EXPECT_EQ(s.samples_merged(), 0u);
  EXPECT_EQ(scheduler_.JobEpoch(id), 1u);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "liar");
  EXPECT_EQ(CompleteOk(in_flight).status, CompleteStatus::kIgnored) << "its lease went with the restart";
  EXPECT_FALSE(scheduler_.TryLease({"honest", {}}).has_value()) << "held until the restart is stored";
  const std::vector<Checkpoint> cps = scheduler_.CollectCheckpoints(/*due=*/false);
  ASSERT_EQ(cps.size(), 1u) << "the empty image is checkpointed at once";
  EXPECT_GT(cps[0].merge_seq, old_seq) << "it supersedes the old checkpoint";
  EXPECT_TRUE(cps[0].merged_task_ids.empty());
  EXPECT_EQ(cps[0].epoch, 1u);
  EXPECT_EQ(cps[0].convicted, std::vector<std::string>{"liar"}) << "with the epoch, who was convicted";
  scheduler_.CheckpointStored(cps[0], CheckpointSeal{0, 1}, "/r.acc");
  EXPECT_FALSE(scheduler_.TryLease({"honest", {}}).has_value())
      << "held until its row (epoch, convicted) is stored too";
  const RowBatch rows = scheduler_.CollectRows();
  bool row_found = false;
  for (const JobRow& row : rows.jobs)
    if (row.job_id == id) {
      row_found = true;
      EXPECT_EQ(row.epoch, 1u);
      EXPECT_EQ(row.convicted, "liar");
    }
  EXPECT_TRUE(row_found);
  scheduler_.RowsStored(rows);
  EXPECT_FALSE(scheduler_.TryLease({"liar", {}}).has_value()) << "blocklisted for the job";
  while (std::optional<Lease> l = scheduler_.TryLease({"honest", {}})) CompleteOk(*l);
  s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  const JobSnapshot a = scheduler_.Snapshot(id, true), b = scheduler_.Snapshot(reference, true);
  ASSERT_TRUE(a.image && b.image);
  EXPECT_EQ(a.image->samples_merged, b.image->samples_merged);
  for (size_t p = 0; p < b.image->image.size(); ++p)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(a.image->image[p][c], b.image->image[p][c]) << p;
  EXPECT_FALSE(scheduler_.ConvictWorker(id, "honest", 0, "late")) << "a finished job is left as it is";
}

}  // namespace
}  // namespace pf::server

namespace pf::server {
namespace {

// The restarted job's task list is the plan's static tasks again: a hierarchical job whose task
// source had added localization tasks restarts without throwing, and ends.
TEST(SchedulerConviction, AHierarchicalJobRestartsFromItsStaticTasks) {
  FakeClock clock;
  Scheduler scheduler(clock, {});
  std::unique_ptr<Job> job = scheduler.PrepareJob(testing::MakeConfig(SmallHierarchy(), 12, 10));
  const std::string id = job->id();
  const size_t static_tasks = job->num_tasks();
  scheduler.AddJob(std::move(job));
  while (scheduler.Status(id).tasks_total() == static_tasks) {
    const std::optional<Lease> l = scheduler.TryLease({"w", {}});
    ASSERT_TRUE(l.has_value()) << "the source never added tasks";
    scheduler.Complete(l->lease_id, l->worker_id, SyntheticResult(l->task, 12, 10));
  }
  ASSERT_TRUE(scheduler.ConvictWorker(id, "w", 0, "wrong result"));
  EXPECT_EQ(scheduler.Status(id).tasks_total(), static_tasks);
  scheduler.RowsStored(scheduler.CollectRows());
  for (const Checkpoint& cp : scheduler.CollectCheckpoints(true))
    scheduler.CheckpointStored(cp, {}, "/h.acc");
  while (std::optional<Lease> l = scheduler.TryLease({"honest", {}}))
    scheduler.Complete(l->lease_id, l->worker_id, SyntheticResult(l->task, 12, 10));
  EXPECT_EQ(scheduler.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// A restart is a new run: a time budget spent by the discarded work does not end the restarted job
// at once with an empty image.
TEST_F(SchedulerTest, ARestartedJobGetsItsTimeBudgetAgain) {
  const std::string id = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4, 0, StopRule{.time_budget_seconds = 10}));
  EXPECT_EQ(CompleteOk(MustLease("liar")).status, CompleteStatus::kMerged);
  clock_.Advance(9);
  ASSERT_TRUE(scheduler_.ConvictWorker(id, "liar", 0, "wrong result"));
  clock_.Advance(9);  // a full disk holds the restart that long: the clock starts once it is stored
  scheduler_.Tick();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << "no budget ends an unstored restart";
  scheduler_.RowsStored(scheduler_.CollectRows());
  for (const Checkpoint& cp : scheduler_.CollectCheckpoints(true))
    scheduler_.CheckpointStored(cp, {}, "/t.acc");
  clock_.Advance(2);
  scheduler_.Tick();
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING) << "20 s since submission, 2 s since the restart was stored";
  EXPECT_EQ(CompleteOk(MustLease("honest")).status, CompleteStatus::kMerged);
}

// A worker that presents another worker's lease is blocklisted for the job, but nothing about a
// result is proven (worker ids are self-declared: the name may be anyone's), so its merged result
// stays, the job is not restarted and the holder's lease is intact.
TEST_F(SchedulerTest, AHijackerIsBlocklistedForTheJobWithoutARestart) {
  const std::string id = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4));
  EXPECT_EQ(CompleteOk(MustLease("mallory")).status, CompleteStatus::kMerged);
  const Lease own = MustLease("mallory");
  const Lease held = MustLease("holder");
  EXPECT_TRUE(scheduler_.Extend(held.lease_id, "mallory", 0.5).not_holder);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(scheduler_.JobEpoch(id), 0u);
  EXPECT_EQ(s.tasks_done(), 1u);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "mallory");
  EXPECT_EQ(CompleteOk(own).status, CompleteStatus::kIgnored) << "its own lease was revoked";
  EXPECT_EQ(scheduler_.counters().failed_attempts, 0u) << "revoked, not failed";
  EXPECT_EQ(CompleteOk(held).status, CompleteStatus::kMerged) << "the holder's lease is intact";
  EXPECT_FALSE(scheduler_.TryLease({"mallory", {}}).has_value());
  for (const JobRow& row : scheduler_.CollectRows().jobs) {
    if (row.job_id == id) {
      EXPECT_EQ(row.convicted, "mallory") << "kept across a restart of the coordinator";
    }
  }
}

// The restart's row reached the disk before its checkpoint (the checkpoint failed, full disk):
// the job's clock starts once both are stored, not at the row — else the hold would spend the
// budget and the job would end at once with an empty image.
TEST_F(SchedulerTest, ARestartsClockStartsWhenBothItsRowAndCheckpointAreStored) {
  const std::string id = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4, 0, StopRule{.time_budget_seconds = 10}));
  EXPECT_EQ(CompleteOk(MustLease("liar")).status, CompleteStatus::kMerged);
  ASSERT_TRUE(scheduler_.ConvictWorker(id, "liar", 0, "wrong result"));
  const std::vector<Checkpoint> cps = scheduler_.CollectCheckpoints(true);
  scheduler_.CheckpointNotStored(id, cps.at(0).merge_seq, "No space left on device");
  scheduler_.RowsStored(scheduler_.CollectRows());
  clock_.Advance(30);  // the disk stays full for a while
  scheduler_.Tick();
  for (const Checkpoint& cp : scheduler_.CollectCheckpoints(true))
    scheduler_.CheckpointStored(cp, {}, "/c.acc");
  clock_.Advance(1);
  scheduler_.Tick();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << "1 s since the restart was stored";
  EXPECT_EQ(CompleteOk(MustLease("honest")).status, CompleteStatus::kMerged);
}

// Restarted after a conviction, nothing merged since, and the time budget runs out (its workers
// were all convicted, or none came): the job fails — an empty image is no result.
TEST_F(SchedulerTest, ARestartedJobWithNothingMergedFailsWhenItsBudgetRunsOut) {
  const std::string id = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4, 0, StopRule{.time_budget_seconds = 10}));
  EXPECT_EQ(CompleteOk(MustLease("liar")).status, CompleteStatus::kMerged);
  ASSERT_TRUE(scheduler_.ConvictWorker(id, "liar", 0, "wrong result"));
  for (const Checkpoint& cp : scheduler_.CollectCheckpoints(true))
    scheduler_.CheckpointStored(cp, {}, "/c.acc");
  scheduler_.RowsStored(scheduler_.CollectRows());
  EXPECT_FALSE(scheduler_.TryLease({"liar", {}}).has_value());
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING)
      << "only a convicted worker is blocklisted: the job waits for an honest one";
  clock_.Advance(11);
  scheduler_.Tick();
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("nothing merged since the job restarted"));
}

// A worker convicted while a result of its own is being checked (its lease pinned, so not
// revoked): that result is not merged, and the task is queued again.
TEST_F(SchedulerTest, AResultInFlightWhenItsWorkerIsConvictedIsNotMerged) {
  const std::string id = Submit(MakeConfig(MultipleMaps(4, 0), 4, 4));
  const Lease verifier_lease = MustLease("v");
  probe_.Set([&](const std::string&) {
    // Its image holds nothing of v's: no restart, only a blocklisting.
    EXPECT_FALSE(scheduler_.ConvictWorker(id, "v", verifier_lease.task_id, "a wrong verification"));
  });
  EXPECT_EQ(CompleteOk(verifier_lease).status, CompleteStatus::kIgnored);
  probe_.Set(nullptr);
  const v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.tasks_done(), 0u);
  EXPECT_EQ(s.samples_merged(), 0u);
  EXPECT_EQ(scheduler_.JobEpoch(id), 0u);
  const Lease again = MustLease("honest");
  EXPECT_EQ(again.task_id, verifier_lease.task_id) << "queued again";
  EXPECT_EQ(CompleteOk(again).status, CompleteStatus::kMerged);
}

}  // namespace
}  // namespace pf::server
