#pragma once
// Access control for the coordinator's services, checked once for every call by gRPC itself:
// an AuthMetadataProcessor attached to the server credentials (coordinator.cpp), so a new RPC
// cannot forget it. Two roles, two credentials (docs/security.md, "Authentication and roles"):
//   /photonfarm.v1.RenderService/*  needs `authorization: Bearer <client token>`
//   /photonfarm.v1.WorkerService/*  needs `authorization: Bearer <worker token>`
// A role without a configured token is open. A missing or unknown token is UNAUTHENTICATED; the
// other role's token is PERMISSION_DENIED (a worker credential cannot submit or read jobs, a
// client credential cannot lease or complete tasks). Health checking and reflection stay open
// (liveness probes; the schema is public), every other method is refused when any token is set.
// Token comparisons take the same time wherever the first difference is.

#include <grpcpp/security/auth_metadata_processor.h>

#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace pf::server {

struct RoleTokens {
  std::string client;  // RenderService; "" = open
  std::string worker;  // WorkerService; "" = open
  bool any() const { return !client.empty() || !worker.empty(); }
};

// The decision for one call, separate from gRPC's types so it can be tested directly.
// `method` is the HTTP/2 :path ("/photonfarm.v1.RenderService/SubmitJob"), `authorization`
// the metadata value ("" if absent).
grpc::Status Authorize(const RoleTokens& tokens, std::string_view method, std::string_view authorization);

// The web status page (server/http/status_page.h) is a view of RenderService: it is authorized
// as this RenderService method, so it needs the client credential.
inline constexpr std::string_view kWebStatusMethod = "/photonfarm.v1.RenderService/WebStatus";

class RoleAuthProcessor final : public grpc::AuthMetadataProcessor {
 public:
  // A refused WorkerService call: the announced worker id ("" if none) and the refusal.
  using WorkerRefused = std::function<void(const std::string& announced_id, const grpc::Status& status)>;

  // `worker_needs_certificate`: WorkerService calls must come over TLS with a verified client
  // certificate (the server's --tls-client-ca; gRPC has checked it in the handshake).
  // `on_worker_refused` runs on gRPC's thread for every refused WorkerService call: it must not
  // block (FarmActivity::WorkerRefused).
  RoleAuthProcessor(RoleTokens tokens, bool worker_needs_certificate, WorkerRefused on_worker_refused = {})
      : tokens_(std::move(tokens)),
        worker_needs_certificate_(worker_needs_certificate),
        on_worker_refused_(std::move(on_worker_refused)) {}
  bool IsBlocking() const override { return false; }  // memory only: runs on gRPC's thread
  grpc::Status Process(const InputMetadata& auth_metadata, grpc::AuthContext* context,
                       OutputMetadata* consumed_auth_metadata, OutputMetadata* response_metadata) override;

 private:
  RoleTokens tokens_;
  bool worker_needs_certificate_;
  WorkerRefused on_worker_refused_;
};

}  // namespace pf::server
