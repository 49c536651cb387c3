#pragma once
// The host of a gRPC peer string (ServerContext::peer()): "ipv4:10.0.0.7:4242" → "10.0.0.7",
// "ipv6:[::1]:4242" (or gRPC's URI-escaped "ipv6:%5B::1%5D:4242") → "::1". Anything else (a
// unix socket, an unknown scheme) is returned as it is. The address of an established TCP
// connection, so a caller cannot choose it as it chooses the ids it announces.

#include <string>
#include <string_view>

namespace pf::server {

std::string PeerHost(std::string_view peer);

}  // namespace pf::server
