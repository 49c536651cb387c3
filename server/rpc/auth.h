#pragma once
// Bearer-token access control for RenderService and WorkerService (docs/design.md, G5). When a
// token is configured (--token-file or PF_TOKEN), every call must carry the metadata
// `authorization: Bearer <token>`; a missing or wrong token is UNAUTHENTICATED. The comparison
// takes the same time wherever the first difference is. The health and reflection services stay
// open (liveness probes; the schema is not a secret).

#include <string>

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

namespace pf::server {

class BearerAuth {
 public:
  explicit BearerAuth(std::string token = "") : token_(std::move(token)) {}
  bool enabled() const { return !token_.empty(); }
  grpc::Status Check(const grpc::ServerContextBase& context) const;

 private:
  std::string token_;
};

}  // namespace pf::server
