// Result verification (server/scheduling/result_verification.h; docs/farm.md "Result
// verification") in the scheduler with a FakeClock and a referee the test answers for: results
// chosen at random or flagged by the outlier test are rendered again by another worker under an
// ordinary lease and never merged; a mismatch goes to the referee and the worker whose result
// differs from the referee's is convicted; the job does not succeed while a verification is
// pending; verification leases expire, fail and return like task leases; with no other worker,
// the referee verifies.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <deque>

#include "server/assembly/result_merger.h"
#include "server/clock.h"
#include "server/scheduling/result_verification.h"
#include "server/scheduling/scheduler.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using ::testing::HasSubstr;
using testing::MakeConfig;
using ::testing::MatchesRegex;
using testing::MultipleMaps;
using testing::SyntheticResult;
namespace v1 = photonfarm::v1;

TEST(OutlierTest, FlagsScaledAndBlackResultsNotHonestOnes) {
  const std::vector<double> others = {1.0, 1.04, 0.97, 1.02, 0.95};
  EXPECT_FALSE(ScoreAgainst(1.03, others).outlier);
  EXPECT_FALSE(ScoreAgainst(0.9, others).outlier);
  EXPECT_TRUE(ScoreAgainst(1.5, others).outlier);
  EXPECT_TRUE(ScoreAgainst(1000, others).outlier);
  EXPECT_TRUE(ScoreAgainst(0, others).outlier);
  EXPECT_FALSE(ScoreAgainst(1000, std::vector<double>{1.0, 1.0}).tested) << "fewer than 3 others";
  // A black region is black in every honest result: no division by zero, no false alarm.
  const std::vector<double> black = {0, 0, 0, 0};
  EXPECT_FALSE(ScoreAgainst(0, black).outlier);
  EXPECT_TRUE(ScoreAgainst(0.5, black).outlier);
  // Identical honest results (a quiet region): the relative floor keeps small deviations quiet.
  EXPECT_FALSE(ScoreAgainst(1.1, std::vector<double>{1, 1, 1, 1}).outlier);
  EXPECT_TRUE(ScoreAgainst(1.5, std::vector<double>{1, 1, 1, 1}).outlier);
}

// A referee the test answers for.
class FakeReferee final : public RefereeHook {
 public:
  void Judge(RefereeCase c) override { cases.push_back(std::move(c)); }
  std::deque<RefereeCase> cases;
};

class VerificationTest : public ::testing::Test {
 protected:
  explicit VerificationTest(VerificationOptions v = {.fraction = 1, .outliers = false})
      : scheduler_(clock_, SchedulerOptions{.lease_seconds = 30, .max_attempts = 3, .verification = v}) {
    scheduler_.SetReferee(&referee_);
  }

  std::string Submit(const JobConfig& config) {
    std::unique_ptr<Job> job = scheduler_.PrepareJob(config);
    const std::string id = job->id();
    scheduler_.AddJob(std::move(job));
    return id;
  }
  static std::vector<float> Honest(const Lease& lease) {
    return SyntheticResult(lease.task, lease.config->camera.width, lease.config->camera.height);
  }
  static std::vector<float> Scaled(const Lease& lease, float factor) {
    std::vector<float> sums = Honest(lease);
    for (float& v : sums) v *= factor;
    return sums;
  }
  // The worker polls (no work yet): a live worker the scheduler knows, which may verify.
  void Known(const std::string& worker) { EXPECT_FALSE(scheduler_.TryLease({worker, {}}).has_value()); }
  Lease MustLease(const std::string& worker) {
    std::optional<Lease> lease = scheduler_.TryLease({worker, {}});
    if (!lease) throw std::runtime_error(worker + " got no lease");
    return *lease;
  }
  CompleteStatus Send(const Lease& lease, const std::vector<float>& sums) {
    return scheduler_.Complete(lease.lease_id, lease.worker_id, sums).status;
  }
  int Events(const std::string& job, const std::string& kind, const std::string& worker = "*") {
    int n = 0;
    for (const v1::TaskEvent& e : scheduler_.activity().Events(job))
      n += e.kind() == kind && (worker == "*" || e.worker_id() == worker);
    return n;
  }
  // The referee's answer: the digest of the honest render of the case's task.
  void AnswerHonestly() {
    ASSERT_FALSE(referee_.cases.empty());
    const RefereeCase c = referee_.cases.front();
    referee_.cases.pop_front();
    scheduler_.RefereeVerdict(
        c.verification_id,
        ResultMerger::Digest(SyntheticResult(c.task, c.config->camera.width, c.config->camera.height)));
  }
  // The row of a restarted job (epoch, convicted workers), then its empty checkpoint, are stored:
  // it leases again.
  void StoreRestart() {
    scheduler_.RowsStored(scheduler_.CollectRows());
    for (const Checkpoint& cp : scheduler_.CollectCheckpoints(false))
      scheduler_.CheckpointStored(cp, CheckpointSeal{0, 1}, "/restart.acc");
  }

  FakeClock clock_;
  FakeReferee referee_;
  Scheduler scheduler_;
};

// Every merged result is chosen (fraction 1): another worker gets an ordinary lease of the same
// task — the same lease id form, the next attempt number — its identical result is answered
// "not merged" and adds no samples, and the job succeeds only after both verifications.
TEST_F(VerificationTest, AChosenResultIsRenderedAgainByAnotherWorkerUnderAnOrdinaryLeaseAndNeverMerged) {
  Known("w2");
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 8, 4));
  for (int i = 0; i < 2; ++i) {
    const Lease l = MustLease("w1");
    ASSERT_EQ(Send(l, Honest(l)), CompleteStatus::kMerged);
  }
  v1::JobStatus s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING) << "not before its results are verified";
  EXPECT_EQ(s.tasks_done(), 2u);
  EXPECT_EQ(s.verifications_pending(), 2u);
  const uint64_t samples = s.samples_merged();
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value()) << "never the worker whose result it checks";
  for (int i = 0; i < 2; ++i) {
    const Lease check = MustLease("w2");
    EXPECT_EQ(check.job_id, id);
    EXPECT_EQ(check.attempt, 2u) << "the next attempt, as a retry's";
    EXPECT_THAT(check.lease_id,
                MatchesRegex(id + "\\." + std::to_string(check.task_id) + "\\.2\\.[0-9a-f]{32}"));
    EXPECT_FALSE(check.chunk.has_value());
    ASSERT_TRUE(check.config);
    EXPECT_EQ(Send(check, Honest(check)), CompleteStatus::kVerification);
  }
  s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.samples_merged(), samples) << "a verification's result is never merged";
  EXPECT_EQ(s.results_verified(), 2u);
  EXPECT_EQ(s.verifications_pending(), 0u);
  EXPECT_EQ(Events(id, "verified", "w2"), 2);
  EXPECT_EQ(scheduler_.counters().verification_leases, 2u);
  EXPECT_TRUE(referee_.cases.empty());
}

// The original lied (x1.5): the honest verifier's result differs, the referee's render agrees with
// the verifier, and the liar is convicted: blocklisted, the job restarted without it, and it ends
// in the honest image.
TEST_F(VerificationTest, AMismatchGoesToTheRefereeAndTheWorkerWhoseResultDiffersFromItsIsConvicted) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 8, 4));
  const Lease lie = MustLease("liar");
  ASSERT_EQ(Send(lie, Scaled(lie, 1.5f)), CompleteStatus::kMerged);
  const Lease check = MustLease("honest");
  ASSERT_EQ(check.task_id, lie.task_id) << "verifications come before new tasks";
  ASSERT_EQ(Send(check, Honest(check)), CompleteStatus::kVerification);
  EXPECT_EQ(Events(id, "mismatch", "honest"), 1);
  ASSERT_EQ(referee_.cases.size(), 1u);
  EXPECT_EQ(referee_.cases.front().task.task_id, lie.task_id);
  EXPECT_EQ(scheduler_.Status(id).verifications_pending(), 1u) << "until the referee has spoken";
  AnswerHonestly();
  v1::JobStatus s = scheduler_.Status(id);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "liar");
  EXPECT_EQ(Events(id, "convicted", "liar"), 1);
  EXPECT_EQ(Events(id, "convicted", "honest"), 0);
  EXPECT_EQ(scheduler_.JobEpoch(id), 1u) << "restarted without it";
  EXPECT_EQ(s.tasks_done(), 0u);
  StoreRestart();
  EXPECT_FALSE(scheduler_.TryLease({"liar", {}}).has_value());
  // The honest worker renders everything; each of its results is verified by the referee (no
  // other worker may).
  while (std::optional<Lease> l = scheduler_.TryLease({"honest", {}}))
    ASSERT_EQ(Send(*l, Honest(*l)), CompleteStatus::kMerged);
  while (!referee_.cases.empty()) AnswerHonestly();
  s = scheduler_.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.results_verified(), 2u);
}

// The verifier lied: the referee agrees with the original, and the verifier is convicted.
TEST_F(VerificationTest, ALyingVerifierIsConvictedAndTheOriginalResultStands) {
  Known("liar");
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 8, 4));
  const Lease first = MustLease("honest");
  ASSERT_EQ(Send(first, Honest(first)), CompleteStatus::kMerged);
  const Lease check = MustLease("liar");
  ASSERT_EQ(Send(check, Scaled(check, 0.0f)), CompleteStatus::kVerification);
  AnswerHonestly();
  const v1::JobStatus s = scheduler_.Status(id);
  ASSERT_EQ(s.blocklisted_workers_size(), 1);
  EXPECT_EQ(s.blocklisted_workers(0).worker_id(), "liar");
  EXPECT_EQ(Events(id, "convicted", "honest"), 0);
  // The liar's result was never merged: the image holds nothing of it, and the honest work stays.
  EXPECT_EQ(scheduler_.JobEpoch(id), 0u) << "not restarted";
  EXPECT_EQ(s.tasks_done(), 1u);
}

// A verification's lease is bound to its worker; a returned one is queued again without a failure;
// one that runs out counts against its worker, which never gets that verification again; after
// failures on 3 distinct verifiers the referee renders it. The job waits for all of it.
TEST_F(VerificationTest, VerificationLeasesAreBoundExpireFailAndReturnLikeTaskLeases) {
  for (const char* w : {"w2", "w3", "w4"}) Known(w);
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 8, 4));
  const Lease first = MustLease("w1");
  ASSERT_EQ(Send(first, Honest(first)), CompleteStatus::kMerged);
  Lease check = MustLease("w2");
  // A stranger presenting the lease is refused and convicted (blocklisted for the job); nothing of
  // its is in the image, so the job goes on.
  EXPECT_EQ(scheduler_.Complete(check.lease_id, "thief", Honest(check)).status, CompleteStatus::kNotHolder);
  EXPECT_TRUE(scheduler_.Extend(check.lease_id, "thief", 0.5).not_holder);
  EXPECT_EQ(scheduler_.Fail(check.lease_id, "thief", "sabotage", false), FailOutcome::kNotHolder);
  EXPECT_EQ(Events(id, "convicted", "thief"), 1) << "blocklisted at the first";
  EXPECT_EQ(scheduler_.JobEpoch(id), 0u) << "not restarted";
  ASSERT_EQ(scheduler_.Status(id).blocklisted_workers_size(), 1);
  EXPECT_EQ(scheduler_.Status(id).blocklisted_workers(0).worker_id(), "thief");
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 1u);
  EXPECT_TRUE(scheduler_.Extend(check.lease_id, "w2", 0.5).ok);
  scheduler_.ReturnLease(check.lease_id);
  EXPECT_EQ(Events(id, "returned", "w2"), 1);
  check = MustLease("w2");  // a returned lease is no failure: w2 may take it again
  clock_.Advance(31);
  scheduler_.Tick();
  EXPECT_EQ(Events(id, "expired", "w2"), 1);
  EXPECT_EQ(Send(check, Honest(check)), CompleteStatus::kIgnored) << "ran out";
  EXPECT_FALSE(scheduler_.TryLease({"w2", {}}).has_value()) << "it failed this verification";
  check = MustLease("w3");
  EXPECT_EQ(scheduler_.Fail(check.lease_id, "w3", "out of memory", false), FailOutcome::kFailed);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING) << "not retryable fails no job here";
  check = MustLease("w4");
  EXPECT_TRUE(referee_.cases.empty());
  EXPECT_EQ(Send(check, std::vector<float>{1, 2}), CompleteStatus::kRejected);
  // w4's rejection was the third distinct verifier's failure: the coordinator renders it.
  EXPECT_FALSE(scheduler_.TryLease({"w5", {}}).has_value());
  ASSERT_EQ(referee_.cases.size(), 1u);
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING);
  AnswerHonestly();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id).blocklisted_workers_size(), 1) << "the thief only: one failure each";
}

// A one-worker farm: nobody else may verify, so the job, once its tasks are merged, hands its
// verifications to the referee, and succeeds on its verdicts.
TEST_F(VerificationTest, AOneWorkerFarmsVerificationsGoToTheReferee) {
  const std::string id = Submit(MakeConfig(MultipleMaps(2, 0), 8, 4));
  for (int i = 0; i < 2; ++i) {
    const Lease l = MustLease("only");
    ASSERT_EQ(Send(l, Honest(l)), CompleteStatus::kMerged);
  }
  EXPECT_EQ(referee_.cases.size(), 2u) << "no other worker may verify";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING);
  AnswerHonestly();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_RUNNING);
  AnswerHonestly();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(scheduler_.Status(id).results_verified(), 2u);
  EXPECT_EQ(Events(id, "refereed"), 2);
}

// Another live worker may verify: the verification waits for it — until it is lost (silent for two
// lease periods), then the referee renders it.
TEST_F(VerificationTest, AVerificationWaitsForAnotherLiveWorkerAndGoesToTheRefereeOnceItIsLost) {
  Known("w2");
  const std::string id = Submit(MakeConfig(MultipleMaps(1, 0), 8, 4));
  const Lease l = MustLease("w1");
  ASSERT_EQ(Send(l, Honest(l)), CompleteStatus::kMerged);
  scheduler_.Tick();
  EXPECT_TRUE(referee_.cases.empty()) << "w2 may still verify it";
  clock_.Advance(61);
  scheduler_.Tick();
  ASSERT_EQ(referee_.cases.size(), 1u) << "w2 is lost";
  AnswerHonestly();
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// The referee can say nothing (it cannot render): a result no worker could verify stays merged,
// unverified; a mismatch it cannot decide fails the job (its image cannot be trusted).
TEST_F(VerificationTest, ARefereeThatCannotRenderLeavesAResultUnverifiedOrFailsADisputedJob) {
  const std::string a = Submit(MakeConfig(MultipleMaps(1, 0), 8, 4));
  const Lease l = MustLease("only");
  ASSERT_EQ(Send(l, Honest(l)), CompleteStatus::kMerged);
  ASSERT_EQ(referee_.cases.size(), 1u);
  scheduler_.RefereeVerdict(referee_.cases.front().verification_id, "", "scene gone");
  referee_.cases.clear();
  EXPECT_EQ(scheduler_.Status(a).state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(Events(a, "unverified"), 1);

  const std::string b = Submit(MakeConfig(MultipleMaps(1, 0), 8, 4));
  const Lease first = MustLease("w1");
  ASSERT_EQ(Send(first, Honest(first)), CompleteStatus::kMerged);
  const Lease check = MustLease("w2");
  ASSERT_EQ(Send(check, Scaled(check, 2.0f)), CompleteStatus::kVerification);
  ASSERT_EQ(referee_.cases.size(), 1u);
  scheduler_.RefereeVerdict(referee_.cases.front().verification_id, "", "scene gone");
  const v1::JobStatus s = scheduler_.Status(b);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("could not render the task to decide"));
}

// Only chosen results are verified: the CSPRNG's draw against the fraction (here a fixed sequence).
TEST(VerificationChoice, TheDrawAgainstTheFractionChoosesWhatIsVerified) {
  FakeClock clock;
  FakeReferee referee;
  Scheduler scheduler(clock, SchedulerOptions{.verification = {.fraction = 0.25, .outliers = false}});
  scheduler.SetReferee(&referee);
  std::deque<double> draws = {0.1, 0.3, 0.9, 0.2};
  scheduler.SetVerificationRandomForTest([&] {
    const double d = draws.front();
    draws.pop_front();
    return d;
  });
  std::unique_ptr<Job> job = scheduler.PrepareJob(MakeConfig(MultipleMaps(4, 0), 8, 4));
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  for (int i = 0; i < 4; ++i) {
    const Lease l = scheduler.TryLease({"w1", {}}).value_or(Lease{});
    ASSERT_EQ(scheduler.Complete(l.lease_id, "w1", SyntheticResult(l.task, 8, 4)).status,
              CompleteStatus::kMerged);
  }
  EXPECT_TRUE(draws.empty());
  EXPECT_EQ(scheduler.Status(id).verifications_pending(), 2u) << "0.1 and 0.2 are below 0.25";
}

// The outlier test alone (no random verification): results of one tile over several maps; a
// result scaled by 1.5, 1000 or 0 is verified, an honest one is not.
class OutlierVerificationTest : public VerificationTest {
 protected:
  OutlierVerificationTest() : VerificationTest({.fraction = 0, .outliers = true}) {}
};

TEST_F(OutlierVerificationTest, ResultsScaledBy1Point5Or1000Or0AreVerifiedHonestOnesAreNot) {
  const std::string id = Submit(MakeConfig(MultipleMaps(12, 0), 8, 4));
  for (int i = 0; i < 4; ++i) {
    const Lease l = MustLease("w1");
    ASSERT_EQ(Send(l, Honest(l)), CompleteStatus::kMerged);
  }
  EXPECT_EQ(scheduler_.Status(id).verifications_pending(), 0u);
  uint64_t pending = 0;
  for (const float factor : {1.5f, 1000.0f, 0.0f}) {
    const Lease l = MustLease("w1");
    ASSERT_EQ(Send(l, Scaled(l, factor)), CompleteStatus::kMerged);
    EXPECT_EQ(scheduler_.Status(id).verifications_pending(), ++pending) << "x" << factor;
    const Lease honest = MustLease("w1");
    ASSERT_EQ(Send(honest, Honest(honest)), CompleteStatus::kMerged);
    EXPECT_EQ(scheduler_.Status(id).verifications_pending(), pending) << "an honest result after x" << factor;
  }
}

}  // namespace
}  // namespace pf::server
