// The gRPC handlers alone, over a real loopback server, with a scripted coordinator behind the one
// interface they call (server/rpc/coordinator_api.h): each outcome of an operation becomes the
// documented status code naming the field, a refused request never reaches the coordinator, and a
// merged result is acknowledged only when the coordinator says it is stored.
#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>
#include <gtest/gtest.h>

#include <atomic>
#include <memory>
#include <stdexcept>
#include <string>

#include "common/core/error.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "server/errors.h"
#include "server/rpc/render_service.h"
#include "server/rpc/watch_hub.h"
#include "server/rpc/worker_service.h"

namespace pf::server {
namespace {
namespace v1 = photonfarm::v1;

// Every operation fails the test unless a test scripts it: a handler that reaches the coordinator
// where it should not is caught.
class ScriptedCoordinator final : public CoordinatorApi {
 public:
  Executor pool{1};
  std::atomic<int> calls{0};
  std::function<AdmittedJob(const v1::JobSpec&)> admit_job;
  std::function<v1::JobStatus(const std::string&)> job_status;
  std::function<std::optional<std::string>(const WorkerHello&)> worker_seen;
  std::function<FailOutcome()> fail_task;
  std::function<CompleteResult()> complete_task;
  std::string not_stored;  // AcknowledgeWhenStored's answer

  Executor& executor() override { return pool; }
  Reservation AdmitSceneUpload(const std::string&, uint64_t) override { return Unexpected<Reservation>(); }
  UploadResult StoreScene(const SceneBundle&, const Reservation&) override {
    return Unexpected<UploadResult>();
  }
  AdmittedJob AdmitJob(const v1::JobSpec& spec, const std::string&) override {
    ++calls;
    return admit_job ? admit_job(spec) : Unexpected<AdmittedJob>();
  }
  std::string SubmitJob(AdmittedJob) override { return Unexpected<std::string>(); }
  v1::JobStatus JobStatus(const std::string& id) override {
    ++calls;
    return job_status ? job_status(id) : Unexpected<v1::JobStatus>();
  }
  Scheduler::JobPage ListJobs(bool, uint64_t, size_t) override { return Unexpected<Scheduler::JobPage>(); }
  v1::JobStatus CancelJob(const std::string&) override { return Unexpected<v1::JobStatus>(); }
  v1::JobStatus SetJobPaused(const std::string&, bool) override { return Unexpected<v1::JobStatus>(); }
  v1::DeleteJobResponse DeleteJob(const std::string&) override { return Unexpected<v1::DeleteJobResponse>(); }
  AdmittedRequeue AdmitRequeue(const v1::RequeueJobRequest&, const std::string&) override {
    return Unexpected<AdmittedRequeue>();
  }
  v1::RequeueJobResponse RequeueJob(AdmittedRequeue) override { return Unexpected<v1::RequeueJobResponse>(); }
  std::vector<v1::WorkerInfo> Workers() override { return Unexpected<std::vector<v1::WorkerInfo>>(); }
  std::vector<v1::TaskEvent> JobEvents(const std::string&, uint64_t*) override {
    return Unexpected<std::vector<v1::TaskEvent>>();
  }
  ResolvedImage JobImage(const std::string&, v1::JobStatus*) override { return Unexpected<ResolvedImage>(); }
  std::optional<std::string> WorkerSeen(const WorkerHello& hello) override {
    ++calls;
    return worker_seen ? worker_seen(hello) : Unexpected<std::optional<std::string>>();
  }
  uint64_t LeaseOrWait(const LeaseRequest&, double, std::function<void(std::optional<Lease>)> done) override {
    ++calls;
    done(std::nullopt);
    return 0;
  }
  void CancelWait(uint64_t) override {}
  void ReturnLease(const std::string&) override { Unexpected<int>(); }
  void WorkerLeft(const std::string&) override { Unexpected<int>(); }
  std::optional<BuiltMap> MapFor(const std::string&, uint64_t) override {
    return Unexpected<std::optional<BuiltMap>>();
  }
  ExtendResult ExtendLease(const std::string&, const std::string&, double) override {
    return Unexpected<ExtendResult>();
  }
  CompleteResult CompleteTask(const std::string&, const std::string&, std::span<const float>, RadiancePart,
                              const TaskStats&) override {
    ++calls;
    return complete_task ? complete_task() : Unexpected<CompleteResult>();
  }
  void AcknowledgeWhenStored(const CompleteResult&, std::span<const float>,
                             std::function<void(const std::string&)> answer) override {
    answer(not_stored);
  }
  FailOutcome FailTask(const std::string&, const std::string&, const std::string&, bool) override {
    ++calls;
    return fail_task ? fail_task() : Unexpected<FailOutcome>();
  }
  std::vector<std::pair<std::string, std::filesystem::path>> SceneFiles(const std::string&) override {
    return Unexpected<std::vector<std::pair<std::string, std::filesystem::path>>>();
  }
  DistributedMaps::UploadAdmission BeginPieceUpload(const std::string&, const std::string&) override {
    return Unexpected<DistributedMaps::UploadAdmission>();
  }
  void EndPieceUpload(const std::string&) override {}
  DistributedMaps::Accepted AcceptPiece(const std::string&, const std::string&, const std::string&) override {
    return Unexpected<DistributedMaps::Accepted>();
  }
  BuiltMapFile MapFile(const std::string&) override { return Unexpected<BuiltMapFile>(); }

 private:
  template <typename T>
  static T Unexpected() {
    throw std::logic_error("the coordinator was called where the test did not expect it");
  }
};

class RpcHandlersTest : public ::testing::Test {
 protected:
  void SetUp() override {
    grpc::ServerBuilder builder;
    int port = 0;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
    builder.RegisterService(&render_);
    builder.RegisterService(&worker_);
    server_ = builder.BuildAndStart();
    ASSERT_NE(port, 0);
    auto channel =
        grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
    render_client_ = v1::RenderService::NewStub(channel);
    worker_client_ = v1::WorkerService::NewStub(channel);
  }
  void TearDown() override { server_->Shutdown(); }

  static std::unique_ptr<grpc::ClientContext> Context() {
    auto context = std::make_unique<grpc::ClientContext>();
    context->set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(20));
    return context;
  }

  ScriptedCoordinator coordinator_;
  FakeClock clock_;
  Scheduler scheduler_{clock_, SchedulerOptions{}};
  WatchHub watches_{scheduler_, coordinator_.pool, clock_, Budgets{}};
  RenderServiceImpl render_{coordinator_, watches_};
  WorkerGate open_gate_{RoleTokens{}, /*needs_certificate=*/false};  // no credentials configured
  WorkerServiceImpl worker_{coordinator_, open_gate_};
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<v1::RenderService::Stub> render_client_;
  std::unique_ptr<v1::WorkerService::Stub> worker_client_;
};

TEST_F(RpcHandlersTest, ErrorsOfTheCoordinatorBecomeTheirCodesNamingTheField) {
  coordinator_.admit_job = [](const v1::JobSpec&) -> AdmittedJob {
    throw InputError("spec.camera.width: must be between 1 and 16384");
  };
  v1::SubmitJobResponse submitted;
  grpc::Status st = render_client_->SubmitJob(Context().get(), v1::SubmitJobRequest(), &submitted);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("spec.camera.width:", 0), 0u) << st.error_message();

  coordinator_.job_status = [](const std::string&) -> v1::JobStatus {
    throw NotFoundError("job_id: unknown job");
  };
  v1::GetJobRequest get;
  get.set_job_id("job-1");
  v1::JobStatus status;
  st = render_client_->GetJob(Context().get(), get, &status);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(st.error_message(), "job_id: unknown job");
}

TEST_F(RpcHandlersTest, MalformedRequestsNeverReachTheCoordinator) {
  v1::GetJobRequest get;  // no job id
  v1::JobStatus status;
  grpc::Status st = render_client_->GetJob(Context().get(), get, &status);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("job_id"), std::string::npos) << st.error_message();

  v1::LeaseTaskRequest lease;
  lease.set_worker_id("w1");
  lease.set_wait_seconds(-1);
  v1::LeaseTaskResponse leased;
  st = worker_client_->LeaseTask(Context().get(), lease, &leased);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_NE(st.error_message().find("wait_seconds"), std::string::npos) << st.error_message();

  v1::CompleteTaskRequest complete;
  complete.set_lease_id("job-1.task-1.0.abc");
  complete.set_worker_id("w1");
  complete.set_part(v1::RadiancePart(77));
  v1::CompleteTaskResponse completed;
  st = worker_client_->CompleteTask(Context().get(), complete, &completed);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("part:", 0), 0u) << st.error_message();
  EXPECT_EQ(coordinator_.calls.load(), 0) << "the coordinator was asked about a malformed request";
}

TEST_F(RpcHandlersTest, AWorkerOfAnotherBuildIsRefusedWithTheCoordinatorsReason) {
  coordinator_.worker_seen = [](const CoordinatorApi::WorkerHello& hello) -> std::optional<std::string> {
    if (hello.version == "other") return "worker_version: this worker's build is 'other'";
    return std::nullopt;
  };
  v1::LeaseTaskRequest lease;
  lease.set_worker_id("w1");
  lease.set_worker_version("other");
  v1::LeaseTaskResponse leased;
  grpc::Status st = worker_client_->LeaseTask(Context().get(), lease, &leased);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION);
  EXPECT_EQ(st.error_message(), "worker_version: this worker's build is 'other'");

  lease.set_worker_version("same");
  st = worker_client_->LeaseTask(Context().get(), lease, &leased);
  EXPECT_TRUE(st.ok()) << st.error_message();
  EXPECT_FALSE(leased.has_task());
}

TEST_F(RpcHandlersTest, EachFailOutcomeHasItsCode) {
  v1::FailTaskRequest fail;
  fail.set_lease_id("job-1.task-1.0.abc");
  fail.set_worker_id("w1");
  v1::FailTaskResponse failed;
  const std::pair<FailOutcome, grpc::StatusCode> cases[] = {
      {FailOutcome::kFailed, grpc::StatusCode::OK},
      {FailOutcome::kUnknownLease, grpc::StatusCode::NOT_FOUND},
      {FailOutcome::kNotHolder, grpc::StatusCode::PERMISSION_DENIED}};
  for (const auto& [outcome, code] : cases) {
    coordinator_.fail_task = [outcome = outcome] { return outcome; };
    EXPECT_EQ(worker_client_->FailTask(Context().get(), fail, &failed).error_code(), code);
  }
}

TEST_F(RpcHandlersTest, AMergedResultIsAcknowledgedOnlyOnceStored) {
  coordinator_.complete_task = [] {
    CompleteResult r;
    r.status = CompleteStatus::kMerged;
    r.job_id = "job-1";
    r.task_id = 3;
    return r;
  };
  v1::CompleteTaskRequest complete;
  complete.set_lease_id("job-1.task-3.0.abc");
  complete.set_worker_id("w1");
  v1::CompleteTaskResponse completed;
  grpc::Status st = worker_client_->CompleteTask(Context().get(), complete, &completed);
  EXPECT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(completed.merged());

  coordinator_.not_stored = "No space left on device";
  st = worker_client_->CompleteTask(Context().get(), complete, &completed);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_NE(st.error_message().find("No space left on device"), std::string::npos) << st.error_message();

  coordinator_.complete_task = [] {
    CompleteResult r;
    r.status = CompleteStatus::kRejected;
    r.reason = "a sum is NaN";
    return r;
  };
  v1::CompleteTaskResponse rejected;
  st = worker_client_->CompleteTask(Context().get(), complete, &rejected);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("rgb_sums:", 0), 0u) << st.error_message();
  EXPECT_FALSE(rejected.merged());
}

}  // namespace
}  // namespace pf::server
