// Pausing a job (docs/farm.md "Pausing a job"): the scheduler leases nothing of a paused job while
// a lease in flight still merges, resuming leases again; through PauseJob / ResumeJob the flag is
// stored and a restarted coordinator keeps the job paused; errors name the field or the state.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server/errors.h"
#include "tests/server/server_test_util.h"
#include "tests/util/job_specs.h"

namespace pf::server {
namespace {
using testing::Ctx;
using ::testing::HasSubstr;
using testing::LiveCoordinator;
namespace v1 = photonfarm::v1;

class PauseSchedulerTest : public testing::SchedulerFixture {
 protected:
  CompleteResult Complete(const Lease& lease) {
    const auto& cam = lease.config->camera;
    return scheduler_.Complete(lease.lease_id, lease.worker_id,
                               testing::SyntheticResult(lease.task, cam.width, cam.height));
  }
};

TEST_F(PauseSchedulerTest, APausedJobLeasesNothingButMergesWhatIsInFlight) {
  const std::string id = Submit(testing::MakeConfig(testing::MultipleMaps(3, 0), 4, 4));
  const std::optional<Lease> a = scheduler_.TryLease({"w1", {}});
  ASSERT_TRUE(a.has_value());
  const v1::JobStatus paused = scheduler_.SetPaused(id, true);
  EXPECT_TRUE(paused.paused());
  EXPECT_EQ(paused.state(), v1::JOB_STATE_RUNNING);
  EXPECT_TRUE(scheduler_.SetPaused(id, true).paused()) << "idempotent";
  EXPECT_FALSE(scheduler_.TryLease({"w2", {}}).has_value()) << "a paused job hands out no task";
  // The lease in flight finishes and is merged, once.
  EXPECT_EQ(Complete(*a).status, CompleteStatus::kMerged);
  EXPECT_EQ(scheduler_.Status(id).tasks_done(), 1u);
  EXPECT_EQ(scheduler_.Status(id).tasks_queued(), 2u);
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value());

  EXPECT_FALSE(scheduler_.SetPaused(id, false).paused());
  for (int i = 0; i < 2; ++i) {
    const std::optional<Lease> next = scheduler_.TryLease({"w1", {}});
    ASSERT_TRUE(next.has_value()) << i;
    EXPECT_NE(next->task_id, a->task_id);
    EXPECT_EQ(Complete(*next).status, CompleteStatus::kMerged);
  }
  const v1::JobStatus done = scheduler_.Status(id);
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(done.tasks_done(), 3u);
  EXPECT_EQ(done.samples_merged(), 3u * 4 * 4) << "nothing lost, nothing counted twice";
}

TEST_F(PauseSchedulerTest, OnlyAQueuedOrRunningJobPauses) {
  const std::string id = Submit(testing::MakeConfig(testing::MultipleMaps(1, 0), 4, 4));
  EXPECT_TRUE(scheduler_.SetPaused(id, true).paused()) << "a queued job pauses";
  scheduler_.Cancel(id);
  EXPECT_FALSE(scheduler_.Status(id).paused()) << "a finished job is not shown paused";
  try {
    scheduler_.SetPaused(id, false);
    ADD_FAILURE() << "resuming a cancelled job";
  } catch (const PreconditionError& e) {
    EXPECT_THAT(e.what(), HasSubstr("CANCELLED"));
  }
  EXPECT_THROW(scheduler_.SetPaused("job-unknown", true), NotFoundError);
}

class PauseRpcTest : public testing::LiveCoordinatorTest {
 protected:
  std::string SubmitJob() {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = test_util::CornellPhotonMapSpec(hash_, 32, 24, /*rounds=*/2, /*seed=*/3);
    v1::SubmitJobResponse resp;
    const grpc::Status st = live_->render->SubmitJob(Ctx().get(), req, &resp);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return resp.job_id();
  }
  grpc::Status Pause(const std::string& id, bool paused, v1::JobStatus* status = nullptr) {
    grpc::Status st;
    if (paused) {
      v1::PauseJobRequest req;
      req.set_job_id(id);
      v1::PauseJobResponse resp;
      st = live_->render->PauseJob(Ctx().get(), req, &resp);
      if (status) *status = resp.status();
    } else {
      v1::ResumeJobRequest req;
      req.set_job_id(id);
      v1::ResumeJobResponse resp;
      st = live_->render->ResumeJob(Ctx().get(), req, &resp);
      if (status) *status = resp.status();
    }
    return st;
  }
  v1::JobStatus Get(const std::string& id) {
    v1::GetJobRequest req;
    req.set_job_id(id);
    v1::JobStatus s;
    EXPECT_TRUE(live_->render->GetJob(Ctx().get(), req, &s).ok());
    return s;
  }
};

TEST_F(PauseRpcTest, APausedJobStaysPausedAcrossARestart) {
  const std::string id = SubmitJob();
  v1::JobStatus s;
  ASSERT_TRUE(Pause(id, true, &s).ok());
  EXPECT_TRUE(s.paused());
  EXPECT_FALSE(testing::TakeLease(*live_).has_value());

  live_.reset();  // a restart on the same data directory
  live_ = std::make_unique<LiveCoordinator>(testing::CountingOptions(dir_.path() / "data"));
  EXPECT_TRUE(Get(id).paused());
  EXPECT_FALSE(testing::TakeLease(*live_).has_value()) << "paused after the restart";

  ASSERT_TRUE(Pause(id, false, &s).ok());
  EXPECT_FALSE(s.paused());
  EXPECT_TRUE(testing::TakeLease(*live_).has_value());
  live_.reset();
  live_ = std::make_unique<LiveCoordinator>(testing::CountingOptions(dir_.path() / "data"));
  EXPECT_FALSE(Get(id).paused()) << "the resume is stored too";
}

TEST_F(PauseRpcTest, ErrorsNameTheFieldOrTheState) {
  grpc::Status st = Pause("", true);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(st.error_message(), HasSubstr("job_id"));
  EXPECT_EQ(Pause("job-ffffffffffffffffffffffffffffffff", false).error_code(), grpc::StatusCode::NOT_FOUND);

  const std::string id = SubmitJob();
  v1::CancelJobRequest cancel;
  cancel.set_job_id(id);
  v1::CancelJobResponse cancelled;
  ASSERT_TRUE(live_->render->CancelJob(Ctx().get(), cancel, &cancelled).ok());
  st = Pause(id, true);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_THAT(st.error_message(), HasSubstr("CANCELLED"));
}

}  // namespace
}  // namespace pf::server
