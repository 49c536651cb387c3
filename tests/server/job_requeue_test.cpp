// Requeueing a finished job (server/scheduling/job_requeue.h; docs/farm.md "Requeueing a job"):
// the new spec — a longer plan where the plan has a length, the stop rule replaced, the source
// named — and the refusals naming the field; a source whose results may not be carried (another
// build, a missing checkpoint) gives a new job that renders everything, and one whose final
// checkpoint is not written yet is refused. The carried results themselves are checked end to end
// (tests/e2e/requeue_test.cpp: bit-identical to the longer job, across a coordinator crash).
#include "server/scheduling/job_requeue.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/core/error.h"
#include "server/errors.h"
#include "server/store/sqlite_store.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
namespace v1 = photonfarm::v1;
using testing::FakeCatalog;
using ::testing::HasSubstr;
using testing::SkippingSpec;

class JobRequeueTest : public testing::SchedulerFixture {
 protected:
  // A finished job of `spec` (validated as SubmitJob does) with `done` of its tasks merged.
  Scheduler::FinishedJob Source(const v1::JobSpec& spec, uint64_t done, uint64_t sealed) {
    Scheduler::FinishedJob source;
    source.job_id = "0123456789abcdef0123456789abcdef";
    auto config = ValidateJobSpec(spec, catalog_);
    config.spec.mutable_plan()->set_build(scheduler_.options().build);
    source.config = std::make_shared<const JobConfig>(std::move(config));
    source.state = JobState::kCancelled;
    source.tasks_total = ScheduledTaskCount(*source.config);
    source.tasks_done = done;
    source.seal = CheckpointSeal{sealed, sealed > 0 ? 0x1234u : 0u};
    source.checkpoint_path = (dir_.path() / "checkpoints" / "missing.acc").string();
    return source;
  }
  JobConfig Validated(const v1::JobSpec& spec) { return ValidateJobSpec(spec, catalog_); }

  FakeCatalog catalog_;
  testing::TempDir dir_;
};

TEST_F(JobRequeueTest, TheNewSpecIsTheOldOneMadeLongerWithItsStopRuleReplaced) {
  const Scheduler::FinishedJob source = Source(SkippingSpec(2, 2), 0, 0);
  v1::StopRule stop;
  stop.set_time_budget_seconds(30);
  const v1::JobSpec same = RequeuedSpec(source, 0, nullptr);
  EXPECT_EQ(same.requeued_from(), source.job_id);
  EXPECT_EQ(same.plan().skipping().rounds(), 2u);
  EXPECT_EQ(same.stop().time_budget_seconds(), 0);
  const v1::JobSpec longer = RequeuedSpec(source, 5, &stop);
  EXPECT_EQ(longer.plan().skipping().rounds(), 5u);
  EXPECT_EQ(longer.stop().time_budget_seconds(), 30);
  EXPECT_EQ(longer.seed(), source.config->spec.seed());
  try {
    RequeuedSpec(source, 1, nullptr);
    ADD_FAILURE() << "a shorter plan";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "extend_to: 1 is fewer than the job's 2 rounds");
  }

  v1::JobSpec tails = SkippingSpec(2, 2);
  tails.mutable_plan()->mutable_multiple_maps()->set_maps(2);
  tails.mutable_plan()->mutable_multiple_maps()->set_tile_size(32);
  tails.mutable_plan()->mutable_multiple_maps()->set_tail_tile_size(16);
  Scheduler::FinishedJob tailed = source;
  auto config = std::make_shared<JobConfig>(*source.config);
  config->spec = tails;
  tailed.config = config;
  EXPECT_THAT(
      [&] { RequeuedSpec(tailed, 3, nullptr); },
      ::testing::ThrowsMessage<InputError>(HasSubstr("extend_to: the job's last map ends in tail tiles")));
  EXPECT_EQ(RequeuedSpec(tailed, 0, nullptr).plan().multiple_maps().maps(), 2u) << "a re-run is fine";
  config->spec.mutable_plan()->mutable_maps_in_turn()->set_samples_per_pixel(4);
  EXPECT_THAT(
      [&] { RequeuedSpec(tailed, 8, nullptr); },
      ::testing::ThrowsMessage<InputError>(HasSubstr("extend_to: only a progressive, multiple-maps or")));
}

TEST_F(JobRequeueTest, ResultsOfAnotherBuildOrWithoutTheirCheckpointAreNotCarried) {
  SqliteStore db(dir_.path() / "coordinator.db");
  Scheduler::FinishedJob other_build = Source(SkippingSpec(2, 2), 3, 3);
  auto config = std::make_shared<JobConfig>(*other_build.config);
  config->spec.mutable_plan()->set_build("0.0.1-elsewhere");
  other_build.config = config;
  for (const Scheduler::FinishedJob& source : {other_build, Source(SkippingSpec(2, 2), 3, 3)}) {
    const RequeuedJob job = RequeueValidatedJob(scheduler_, db, dir_.path() / "checkpoints", source,
                                                Validated(RequeuedSpec(source, 0, nullptr)), "");
    EXPECT_EQ(job.tasks_carried, 0u);
    const v1::JobStatus st = scheduler_.Status(job.job_id);
    EXPECT_EQ(st.tasks_queued(), 8u) << "everything is rendered";
    EXPECT_EQ(st.spec().requeued_from(), source.job_id);
  }
  EXPECT_EQ(db.LoadJobs().size(), 2u);
}

TEST_F(JobRequeueTest, AJobWhoseFinalResultsAreNotOnDiskYetIsRefused) {
  SqliteStore db(dir_.path() / "coordinator.db");
  const Scheduler::FinishedJob source = Source(SkippingSpec(2, 2), 3, 2);
  EXPECT_THAT(
      [&] {
        RequeueValidatedJob(scheduler_, db, dir_.path() / "checkpoints", source,
                            Validated(RequeuedSpec(source, 0, nullptr)), "");
      },
      ::testing::ThrowsMessage<UnavailableError>(HasSubstr("its final results are still being written")));
  EXPECT_TRUE(db.LoadJobs().empty()) << "nothing stored";
  EXPECT_TRUE(scheduler_.List(/*include_finished=*/true).empty()) << "nothing scheduled";
}

}  // namespace
}  // namespace pf::server
