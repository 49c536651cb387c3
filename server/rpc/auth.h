#pragma once
// Bearer-token access control for RenderService and WorkerService (Design property 5). When a
// token is configured (--token-file or PF_TOKEN), every call must carry the metadata
// `authorization: Bearer <token>`; a missing or wrong token is UNAUTHENTICATED. The comparison
// takes the same time wherever the first difference is. The health and reflection services stay
// open (liveness probes; the schema is not a secret).

#include <optional>
#include <string>
#include <string_view>

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

namespace pf::server {

class BearerAuth {
 public:
  explicit BearerAuth(std::string token = "") : token_(std::move(token)) {}
  bool enabled() const { return !token_.empty(); }
  grpc::Status Check(const grpc::ServerContextBase& context) const;
  // The same check on an `authorization` value from elsewhere (the web status page's HTTP
  // header); nullopt = no header.
  grpc::Status CheckAuthorization(std::optional<std::string_view> authorization) const;

 private:
  std::string token_;
};

}  // namespace pf::server
