#include "server/rpc/auth.h"

namespace pf::server {
namespace {

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

}  // namespace

grpc::Status BearerAuth::Check(const grpc::ServerContextBase& context) const {
  if (token_.empty()) return grpc::Status::OK;
  const auto& md = context.client_metadata();
  auto it = md.find("authorization");
  if (it == md.end()) return CheckAuthorization(std::nullopt);
  return CheckAuthorization(std::string_view(it->second.data(), it->second.size()));
}

grpc::Status BearerAuth::CheckAuthorization(std::optional<std::string_view> authorization) const {
  if (token_.empty()) return grpc::Status::OK;
  if (!authorization)
    return {grpc::StatusCode::UNAUTHENTICATED, "authorization: missing (expected 'Bearer <token>')"};
  const std::string_view value = *authorization;
  constexpr std::string_view kPrefix = "Bearer ";
  if (value.substr(0, kPrefix.size()) != kPrefix || !ConstantTimeEquals(value.substr(kPrefix.size()), token_))
    return {grpc::StatusCode::UNAUTHENTICATED, "authorization: invalid bearer token"};
  return grpc::Status::OK;
}

}  // namespace pf::server
