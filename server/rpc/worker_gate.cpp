#include "server/rpc/worker_gate.h"

#include <grpc/grpc_security_constants.h>
#include <grpcpp/security/auth_context.h>
#include <grpcpp/server_context.h>

#include "proto/limits.h"
#include "server/peer_host.h"

namespace pf::server {

grpc::Status WorkerGate::Admit(const grpc::CallbackServerContext& context) const {
  std::string_view authorization, announced_id;
  for (const auto& [key, value] : context.client_metadata()) {
    const std::string_view k(key.data(), key.size());
    if (k == "authorization") authorization = std::string_view(value.data(), value.size());
    if (k == limits::kWorkerIdMetadata) announced_id = std::string_view(value.data(), value.size());
  }
  bool has_certificate = false;
  if (needs_certificate_)
    if (const std::shared_ptr<const grpc::AuthContext> auth = context.auth_context())
      has_certificate = !auth->FindPropertyValues(GRPC_X509_PEM_CERT_PROPERTY_NAME).empty();
  grpc::Status status = AdmitWorker(tokens_, needs_certificate_, authorization, has_certificate);
  if (!status.ok() && on_refused_) on_refused_(PeerHost(context.peer()), std::string(announced_id), status);
  return status;
}

}  // namespace pf::server
