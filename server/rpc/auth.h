#pragma once
// Access control for the coordinator's services, checked once for every call before the call does
// anything. Two roles, two credentials (docs/security.md, "Authentication and roles"):
//   /photonfarm.v1.RenderService/*  needs `authorization: Bearer <client token>`
//   /photonfarm.v1.WorkerService/*  needs `authorization: Bearer <worker token>`, and with
//                                   --tls-client-ca a verified client certificate
// A role without a configured token is open. A missing or unknown token is UNAUTHENTICATED; the
// other role's token is PERMISSION_DENIED (a worker credential cannot submit or read jobs, a
// client credential cannot lease or complete tasks). Health checking and reflection stay open
// (liveness probes; the schema is public), every other method is refused when any token is set.
// Token comparisons take the same time wherever the first difference is.
//
// Where: an AuthMetadataProcessor attached to the server credentials (coordinator.cpp) decides
// every call inside gRPC, before its request is read, so a new RPC cannot forget it — except the
// WorkerService calls of a connection from this machine (local credentials) or with a verified
// client certificate, which it passes to WorkerGate (worker_gate.h), the first step of every
// WorkerService handler. gRPC gives a processor no peer address; the gate has it, and refused
// workers are counted per address. An unauthenticated caller on the network never gets that far.

#include <grpcpp/security/auth_metadata_processor.h>

#include <functional>
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

// A WorkerService call: Authorize's, and with `needs_certificate` (--tls-client-ca) a verified
// client certificate (`has_certificate`) as well.
grpc::Status AdmitWorker(const RoleTokens& tokens, bool needs_certificate, std::string_view authorization,
                         bool has_certificate);

// A refused WorkerService call: the caller's address (PeerHost; "" where it is not known: the
// processor's refusals), the worker id it announced ("" if none; untrusted, any caller chooses it)
// and the refusal. Runs on gRPC's thread: must not block (FarmActivity::WorkerRefused).
using OnWorkerRefused = std::function<void(const std::string& address, const std::string& announced_id,
                                           const grpc::Status& status)>;

// The web status page (server/http/status_page.h) is a view of RenderService: it is authorized
// as this RenderService method, so it needs the client credential.
inline constexpr std::string_view kWebStatusMethod = "/photonfarm.v1.RenderService/WebStatus";
inline constexpr std::string_view kWorkerServicePrefix = "/photonfarm.v1.WorkerService/";

class RoleAuthProcessor final : public grpc::AuthMetadataProcessor {
 public:
  // `worker_needs_certificate`: --tls-client-ca (gRPC has verified a presented certificate in the
  // handshake). `on_worker_refused`: the WorkerService calls this processor refuses.
  RoleAuthProcessor(RoleTokens tokens, bool worker_needs_certificate, OnWorkerRefused on_worker_refused = {})
      : tokens_(std::move(tokens)),
        worker_needs_certificate_(worker_needs_certificate),
        on_worker_refused_(std::move(on_worker_refused)) {}
  bool IsBlocking() const override { return false; }  // memory only: runs on gRPC's thread
  grpc::Status Process(const InputMetadata& auth_metadata, grpc::AuthContext* context,
                       OutputMetadata* consumed_auth_metadata, OutputMetadata* response_metadata) override;

 private:
  RoleTokens tokens_;
  bool worker_needs_certificate_;
  OnWorkerRefused on_worker_refused_;
};

}  // namespace pf::server
