// RoleAuthProcessor (server/rpc/auth.h): which calls it decides inside gRPC and which WorkerService
// calls it leaves to WorkerGate, with gRPC's connection properties as a fake AuthContext.
#include "server/rpc/auth.h"

#include <grpc/grpc_security_constants.h>
#include <gtest/gtest.h>

#include <map>
#include <string>
#include <utility>
#include <vector>

#include "proto/limits.h"

namespace pf::server {
namespace {

// The connection properties gRPC gives the processor: its transport and, with a verified client
// certificate, the certificate.
class FakeConnection final : public grpc::AuthContext {
 public:
  FakeConnection(std::string transport, bool certificate) {
    properties_.emplace(GRPC_TRANSPORT_SECURITY_TYPE_PROPERTY_NAME, std::move(transport));
    if (certificate) properties_.emplace(GRPC_X509_PEM_CERT_PROPERTY_NAME, "-----BEGIN CERTIFICATE-----");
  }
  bool IsPeerAuthenticated() const override { return false; }
  std::vector<grpc::string_ref> GetPeerIdentity() const override { return {}; }
  std::string GetPeerIdentityPropertyName() const override { return ""; }
  std::vector<grpc::string_ref> FindPropertyValues(const std::string& name) const override {
    std::vector<grpc::string_ref> values;
    for (auto [it, end] = properties_.equal_range(name); it != end; ++it) values.emplace_back(it->second);
    return values;
  }
  grpc::AuthPropertyIterator begin() const override { return NoProperties(); }
  grpc::AuthPropertyIterator end() const override { return NoProperties(); }
  void AddProperty(const std::string&, const grpc::string_ref&) override {}
  bool SetPeerIdentityPropertyName(const std::string&) override { return false; }

 private:
  struct NoProperties : grpc::AuthPropertyIterator {};
  std::multimap<std::string, std::string> properties_;
};

struct Refusal {
  std::string address, announced_id;
  grpc::StatusCode code;
};

struct Outcome {
  grpc::StatusCode code;
  bool token_consumed;
  std::vector<Refusal> refusals;
};

Outcome Process(const std::string& method, const std::string& token, const FakeConnection& connection,
                bool worker_needs_certificate = false) {
  Outcome outcome;
  RoleAuthProcessor processor({"client-token", "worker-token"}, worker_needs_certificate,
                              [&](const std::string& address, const std::string& id, const grpc::Status& st) {
                                outcome.refusals.push_back({address, id, st.error_code()});
                              });
  const std::string path = method, authorization = token.empty() ? "" : "Bearer " + token, id = "w-7";
  grpc::AuthMetadataProcessor::InputMetadata metadata{{":path", path}, {limits::kWorkerIdMetadata, id}};
  if (!token.empty()) metadata.emplace("authorization", authorization);
  grpc::AuthMetadataProcessor::OutputMetadata consumed, response;
  FakeConnection context = connection;
  outcome.code = processor.Process(metadata, &context, &consumed, &response).error_code();
  outcome.token_consumed = consumed.count("authorization") > 0;
  return outcome;
}

constexpr char kLease[] = "/photonfarm.v1.WorkerService/LeaseTask";
constexpr char kSubmit[] = "/photonfarm.v1.RenderService/SubmitJob";

TEST(RoleAuthProcessor, WorkerCallsFromThisMachineOrWithACertificateAreLeftToTheGate) {
  // Local credentials (loopback) or a verified client certificate: passed on untouched, token kept
  // for the gate, whatever it is; the gate counts any refusal at the caller's address.
  const std::pair<FakeConnection, bool> cases[] = {
      {FakeConnection("local", false), false},  // the loopback listener (--tls-client-ca needs TLS)
      {FakeConnection("ssl", true), true},      // mTLS
  };
  for (const auto& [connection, needs_certificate] : cases)
    for (const std::string token : {"", "guess", "client-token", "worker-token"}) {
      SCOPED_TRACE(token);
      const Outcome o = Process(kLease, token, connection, needs_certificate);
      EXPECT_EQ(o.code, grpc::StatusCode::OK);
      EXPECT_FALSE(o.token_consumed);
      EXPECT_TRUE(o.refusals.empty());
    }
}

TEST(RoleAuthProcessor, WorkerCallsFromTheNetworkWithoutACertificateAreDecidedBeforeTheirRequestIsRead) {
  const FakeConnection tls("ssl", false);
  Outcome o = Process(kLease, "guess", tls);
  EXPECT_EQ(o.code, grpc::StatusCode::UNAUTHENTICATED);
  ASSERT_EQ(o.refusals.size(), 1u);
  EXPECT_EQ(o.refusals[0].address, "") << "a processor is not given the address";
  EXPECT_EQ(o.refusals[0].announced_id, "w-7");
  EXPECT_EQ(Process(kLease, "client-token", tls).code, grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(Process(kLease, "", tls).code, grpc::StatusCode::UNAUTHENTICATED);
  // The right token: admitted here (the gate admits it again), the token kept for the gate.
  o = Process(kLease, "worker-token", tls);
  EXPECT_EQ(o.code, grpc::StatusCode::OK);
  EXPECT_FALSE(o.token_consumed);
  EXPECT_TRUE(o.refusals.empty());
  // --tls-client-ca: the right token without a certificate is refused here.
  o = Process(kLease, "worker-token", tls, /*worker_needs_certificate=*/true);
  EXPECT_EQ(o.code, grpc::StatusCode::UNAUTHENTICATED);
  ASSERT_EQ(o.refusals.size(), 1u);
}

TEST(RoleAuthProcessor, RenderServiceIsAlwaysDecidedHereAndItsTokenConsumed) {
  for (const FakeConnection& connection : {FakeConnection("local", false), FakeConnection("ssl", true)}) {
    Outcome o = Process(kSubmit, "client-token", connection);
    EXPECT_EQ(o.code, grpc::StatusCode::OK);
    EXPECT_TRUE(o.token_consumed) << "handlers never see the client token";
    EXPECT_EQ(Process(kSubmit, "guess", connection).code, grpc::StatusCode::UNAUTHENTICATED);
    EXPECT_EQ(Process(kSubmit, "worker-token", connection).code, grpc::StatusCode::PERMISSION_DENIED);
    EXPECT_TRUE(Process(kSubmit, "guess", connection).refusals.empty())
        << "clients are not listed as workers";
  }
}

}  // namespace
}  // namespace pf::server
