// WorkerGate (server/rpc/worker_gate.h): who may call WorkerService, checked by its handlers, and
// refused callers counted per address. The decision directly, then every method of the service's
// descriptor on an in-process coordinator (127.0.0.1:0, real channel), so a handler that does not
// admit its call through the gate fails here.
#include "server/rpc/worker_gate.h"

#include "server/rpc/auth.h"

#include <google/protobuf/descriptor.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "photonfarm_version.h"
#include "proto/limits.h"
#include "tests/server/server_test_util.h"
#include "tests/util/generic_call.h"

namespace pf::server {
namespace {
using testing::LiveCoordinator;
namespace v1 = photonfarm::v1;

TEST(AdmitWorker, TheWorkerCredentialAndWhereConfiguredACertificate) {
  const RoleTokens tokens{"client-token", "worker-token"};
  EXPECT_TRUE(AdmitWorker(tokens, false, "Bearer worker-token", false).ok());
  EXPECT_EQ(AdmitWorker(tokens, false, "", false).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(AdmitWorker(tokens, false, "Bearer guess", false).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(AdmitWorker(tokens, false, "worker-token", false).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(AdmitWorker(tokens, false, "Bearer client-token", false).error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  // --tls-client-ca: the token alone is not enough.
  const grpc::Status no_certificate = AdmitWorker(tokens, true, "Bearer worker-token", false);
  EXPECT_EQ(no_certificate.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(no_certificate.error_message().find("--tls-client-ca"), std::string::npos);
  EXPECT_TRUE(AdmitWorker(tokens, true, "Bearer worker-token", true).ok());
  // No worker token configured: open (the client's token does not matter), unless a certificate is needed.
  EXPECT_TRUE(AdmitWorker({"client-token", ""}, false, "", false).ok());
  EXPECT_EQ(AdmitWorker({}, true, "", false).error_code(), grpc::StatusCode::UNAUTHENTICATED);
}

class WorkerGateTest : public testing::TokenCoordinatorTest {
 protected:
  // Every method of photonfarm.v1.WorkerService, as its HTTP/2 path.
  static std::vector<std::string> WorkerMethods() {
    const google::protobuf::ServiceDescriptor* service =
        v1::LeaseTaskRequest::descriptor()->file()->pool()->FindServiceByName("photonfarm.v1.WorkerService");
    std::vector<std::string> methods;
    for (int i = 0; service != nullptr && i < service->method_count(); ++i)
      methods.push_back("/photonfarm.v1.WorkerService/" + service->method(i)->name());
    return methods;
  }

  // One call of `method` with an empty request (one message, then the end of the stream), as the
  // caller `announced_id` with `token` ("" = none).
  grpc::Status Call(const std::string& method, const std::string& token, const std::string& announced_id) {
    auto ctx = testing::Ctx(token, 10);
    if (!announced_id.empty()) ctx->AddMetadata(limits::kWorkerIdMetadata, announced_id);
    grpc::GenericStub generic_client(live_->channel);
    const grpc::Slice empty;
    grpc::ByteBuffer request(&empty, 1), response;
    return test_util::BlockingGenericCall(generic_client, ctx.get(), method, &request, &response);
  }

  std::vector<v1::WorkerInfo> Workers() {
    v1::ListWorkersResponse r;
    const grpc::Status st = live_->render->ListWorkers(testing::Ctx("client-token").get(), {}, &r);
    EXPECT_TRUE(st.ok()) << st.error_message();
    return {r.workers().begin(), r.workers().end()};
  }
};

TEST_F(WorkerGateTest, EveryMethodRefusesCallersWithoutTheWorkerCredential) {
  const std::vector<std::string> methods = WorkerMethods();
  ASSERT_GE(methods.size(), 8u) << "the service's descriptor was not found";
  for (const std::string& method : methods) {
    SCOPED_TRACE(method);
    const grpc::Status none = Call(method, "", "intruder");
    EXPECT_EQ(none.error_code(), grpc::StatusCode::UNAUTHENTICATED) << none.error_message();
    EXPECT_EQ(none.error_message(), "authorization: missing (expected 'Bearer <token>')");
    const grpc::Status wrong = Call(method, "guess", "intruder");
    EXPECT_EQ(wrong.error_code(), grpc::StatusCode::UNAUTHENTICATED) << wrong.error_message();
    const grpc::Status client = Call(method, "client-token", "intruder");
    EXPECT_EQ(client.error_code(), grpc::StatusCode::PERMISSION_DENIED) << client.error_message();
    // The worker's credential passes the gate: whatever the empty request gets, it is not a refusal.
    const grpc::Status worker = Call(method, "worker-token", "");
    EXPECT_NE(worker.error_code(), grpc::StatusCode::UNAUTHENTICATED) << worker.error_message();
    EXPECT_NE(worker.error_code(), grpc::StatusCode::PERMISSION_DENIED) << worker.error_message();
  }
  // Counted per address: every refused call of this test came from 127.0.0.1.
  std::optional<v1::WorkerInfo> refused;
  for (const v1::WorkerInfo& w : Workers())
    if (w.refused()) {
      EXPECT_FALSE(refused.has_value()) << "a second refused entry: " << w.ShortDebugString();
      refused = w;
    }
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->peer(), "127.0.0.1");
  EXPECT_EQ(refused->worker_id(), "intruder");
  EXPECT_EQ(refused->refused_calls(), 3 * methods.size());
  EXPECT_EQ(refused->refused_reason(),
            "PERMISSION_DENIED: authorization: WorkerService needs the worker credential");
}

TEST_F(WorkerGateTest, AWorkerWhoseCredentialWorksAgainLeavesItsAddressesEntry) {
  EXPECT_EQ(Call("/photonfarm.v1.WorkerService/LeaseTask", "guess", "w-a").error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(Call("/photonfarm.v1.WorkerService/LeaseTask", "guess", "w-b").error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  const auto refused_ids = [&] {
    for (const v1::WorkerInfo& w : Workers())
      if (w.refused()) return w.worker_id();
    return std::string("(none)");
  };
  EXPECT_EQ(refused_ids(), "w-b, w-a");  // one address, the ids it announced, newest first
  // w-a's token fixed: its accepted poll takes it off the entry; w-b is still refused there.
  v1::LeaseTaskRequest lease;
  lease.set_worker_id("w-a");
  lease.set_worker_version(PF_VERSION);
  v1::LeaseTaskResponse leased;
  const grpc::Status st = live_->worker->LeaseTask(testing::Ctx("worker-token").get(), lease, &leased);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(refused_ids(), "w-b");
  lease.set_worker_id("w-b");
  ASSERT_TRUE(live_->worker->LeaseTask(testing::Ctx("worker-token").get(), lease, &leased).ok());
  EXPECT_EQ(refused_ids(), "(none)");
}

}  // namespace
}  // namespace pf::server
