#include "server/rpc/auth.h"

#include <grpc/grpc_security_constants.h>

#include <algorithm>

#include "proto/limits.h"

namespace pf::server {
namespace {

constexpr std::string_view kRenderService = "/photonfarm.v1.RenderService/";
constexpr std::string_view kWorkerService = kWorkerServicePrefix;
// transport_security_type of gRPC's local credentials (LocalServerCredentials: loopback peers only).
constexpr std::string_view kLocalTransport = "local";
constexpr std::string_view kOpenPrefixes[] = {"/grpc.health.v1.Health/",
                                              "/grpc.reflection.v1alpha.ServerReflection/",
                                              "/grpc.reflection.v1.ServerReflection/"};

bool ConstantTimeEquals(std::string_view a, std::string_view b) {
  unsigned char diff = a.size() == b.size() ? 0 : 1;
  const size_t n = std::max(a.size(), b.size());
  for (size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? static_cast<unsigned char>(a[i]) : 0;
    const unsigned char y = i < b.size() ? static_cast<unsigned char>(b[i]) : 0;
    diff |= x ^ y;
  }
  return diff == 0;
}

bool StartsWith(std::string_view s, std::string_view prefix) {
  return s.substr(0, prefix.size()) == prefix;
}

}  // namespace

grpc::Status Authorize(const RoleTokens& tokens, std::string_view method, std::string_view authorization) {
  const std::string* needed = nullptr;
  const std::string* other = nullptr;
  const char* role = "";
  if (StartsWith(method, kRenderService)) {
    needed = &tokens.client;
    other = &tokens.worker;
    role = "RenderService needs the client credential";
  } else if (StartsWith(method, kWorkerService)) {
    needed = &tokens.worker;
    other = &tokens.client;
    role = "WorkerService needs the worker credential";
  } else {
    for (std::string_view open : kOpenPrefixes)
      if (StartsWith(method, open)) return grpc::Status::OK;
    if (!tokens.any()) return grpc::Status::OK;
    return {grpc::StatusCode::UNAUTHENTICATED, "authorization: unknown service"};
  }
  if (needed->empty()) return grpc::Status::OK;
  constexpr std::string_view kPrefix = "Bearer ";
  if (authorization.empty())
    return {grpc::StatusCode::UNAUTHENTICATED, "authorization: missing (expected 'Bearer <token>')"};
  if (!StartsWith(authorization, kPrefix))
    return {grpc::StatusCode::UNAUTHENTICATED, "authorization: expected 'Bearer <token>'"};
  const std::string_view presented = authorization.substr(kPrefix.size());
  if (ConstantTimeEquals(presented, *needed)) return grpc::Status::OK;
  if (!other->empty() && ConstantTimeEquals(presented, *other))
    return {grpc::StatusCode::PERMISSION_DENIED, std::string("authorization: ") + role};
  return {grpc::StatusCode::UNAUTHENTICATED, "authorization: invalid bearer token"};
}

grpc::Status AdmitWorker(const RoleTokens& tokens, bool needs_certificate, std::string_view authorization,
                         bool has_certificate) {
  grpc::Status status = Authorize(tokens, kWorkerService, authorization);
  if (status.ok() && needs_certificate && !has_certificate)
    status = {grpc::StatusCode::UNAUTHENTICATED,
              "WorkerService needs a client certificate signed by the coordinator's --tls-client-ca"};
  return status;
}

grpc::Status RoleAuthProcessor::Process(const InputMetadata& auth_metadata, grpc::AuthContext* context,
                                        OutputMetadata* consumed_auth_metadata, OutputMetadata*) {
  std::string_view method, authorization, worker_id;
  for (const auto& [key, value] : auth_metadata) {
    const std::string_view k(key.data(), key.size());
    if (k == ":path") method = std::string_view(value.data(), value.size());
    if (k == "authorization") authorization = std::string_view(value.data(), value.size());
    if (k == limits::kWorkerIdMetadata) worker_id = std::string_view(value.data(), value.size());
  }
  if (StartsWith(method, kWorkerService)) {
    const bool has_certificate =
        context != nullptr && !context->FindPropertyValues(GRPC_X509_PEM_CERT_PROPERTY_NAME).empty();
    bool local = false;
    if (context != nullptr)
      for (const grpc::string_ref& type :
           context->FindPropertyValues(GRPC_TRANSPORT_SECURITY_TYPE_PROPERTY_NAME))
        local |= std::string_view(type.data(), type.size()) == kLocalTransport;
    // From this machine or a holder of the farm's certificates: WorkerGate decides, where the
    // caller's address is known. The token stays in the metadata for it.
    if (local || has_certificate) return grpc::Status::OK;
    const grpc::Status status = AdmitWorker(tokens_, worker_needs_certificate_, authorization, false);
    if (!status.ok() && on_worker_refused_) on_worker_refused_("", std::string(worker_id), status);
    return status;  // admitted: the gate admits it again
  }
  grpc::Status status = Authorize(tokens_, method, authorization);
  // The token is consumed: handlers never see it (and cannot log it).
  if (status.ok() && !authorization.empty())
    consumed_auth_metadata->insert({"authorization", std::string(authorization)});
  return status;
}

}  // namespace pf::server
