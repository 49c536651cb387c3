// PeerHost (server/peer_host.h): the address part of gRPC's peer strings.
#include "server/peer_host.h"

#include <gtest/gtest.h>

namespace pf::server {
namespace {

TEST(PeerHost, KeepsTheAddressAndDropsSchemeAndPort) {
  EXPECT_EQ(PeerHost("ipv4:127.0.0.1:54321"), "127.0.0.1");
  EXPECT_EQ(PeerHost("ipv4:198.18.0.2:1"), "198.18.0.2");
  EXPECT_EQ(PeerHost("ipv6:[::1]:54321"), "::1");
  EXPECT_EQ(PeerHost("ipv6:%5B::1%5D:54321"), "::1");  // gRPC's escaped brackets
  EXPECT_EQ(PeerHost("ipv6:%5Bfe80::1%25eth0%5D:7"), "fe80::1%25eth0");
  EXPECT_EQ(PeerHost("unix:/run/pf.sock"), "unix:/run/pf.sock");
  EXPECT_EQ(PeerHost(""), "");
  EXPECT_EQ(PeerHost("ipv4:10.0.0.7"), "10.0.0.7");  // no port: nothing cut but the scheme
}

}  // namespace
}  // namespace pf::server
