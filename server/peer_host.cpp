#include "server/peer_host.h"

namespace pf::server {

std::string PeerHost(std::string_view peer) {
  const bool v4 = peer.starts_with("ipv4:"), v6 = peer.starts_with("ipv6:");
  if (!v4 && !v6) return std::string(peer);
  std::string rest(peer.substr(5));
  if (v6) {
    // gRPC writes the brackets of an IPv6 address escaped ("%5B", "%5D") in its peer URIs.
    for (const auto& [escaped, plain] : {std::pair{"%5B", "["}, std::pair{"%5D", "]"}})
      for (size_t at = rest.find(escaped); at != std::string::npos; at = rest.find(escaped))
        rest.replace(at, 3, plain);
    if (rest.starts_with('[')) {
      const size_t close = rest.find(']');
      if (close != std::string::npos) return rest.substr(1, close - 1);
    }
    return rest;
  }
  const size_t colon = rest.rfind(':');
  return colon == std::string::npos ? rest : rest.substr(0, colon);
}

}  // namespace pf::server
