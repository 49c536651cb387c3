// The status page's gate (server/http/http_gate.h) in-process, with small limits so that each
// rule shows in milliseconds: what it answers by itself (408, 413, 431, 503) never reaches a
// route, and a new connection makes room by closing the one that waited longest. The farm-level
// view (a real coordinator, 400 MiB bodies, 200 slow clients, HTTPS) is in
// tests/e2e/web_status_test.cpp and tests/e2e/security_test.cpp.
#include "server/http/http_gate.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <thread>

#include "tests/util/raw_connection.h"

namespace pf::server {
namespace {

using test_util::RawConnection;
using namespace std::chrono_literals;

// A gated server with one route, GET /, that counts its calls, and any routes `more` adds. Only
// requests with an Authorization header reach them.
class GatedServer {
 public:
  explicit GatedServer(HttpLimits limits, const std::function<void(GatedHttpServer&)>& more = {})
      : server_(limits) {
    // Like the status page: a request without credentials is answered 401 before any route.
    server_.set_pre_routing_handler([](const httplib::Request& req, httplib::Response& res) {
      if (req.has_header("Authorization")) return httplib::Server::HandlerResponse::Unhandled;
      res.status = 401;
      return httplib::Server::HandlerResponse::Handled;
    });
    server_.Get("/", [this](const httplib::Request&, httplib::Response& res) {
      ++routed_;
      res.set_content("ok", "text/plain");
    });
    if (more) more(server_);
    port_ = server_.Start("127.0.0.1", 0);
  }
  GatedHttpServer& server() { return server_; }
  int port() const { return port_; }
  int routed() const { return routed_; }

 private:
  std::atomic<int> routed_{0};  // before server_: its threads stop first
  GatedHttpServer server_;
  int port_ = -1;
};

std::string StatusOf(const std::string& answer) {
  return answer.substr(0, answer.find('\r'));
}

// The answer to one request sent whole on a new connection.
std::string Ask(int port, const std::string& request) {
  RawConnection c(port);
  EXPECT_TRUE(c.connected());
  EXPECT_TRUE(c.Send(request));
  return c.Receive();
}

// Without credentials too: the answer says what is wrong with the request, not 401.
TEST(HttpGate, BodiesAndOversizedHeadsAreAnsweredBeforeAuthenticationAndRoutes) {
  GatedServer s(HttpLimits{.max_head_bytes = 4096});
  ASSERT_GT(s.port(), 0);
  EXPECT_EQ(StatusOf(Ask(s.port(), "GET / HTTP/1.1\r\nHost: x\r\nContent-Length: 5\r\n\r\nhello")),
            "HTTP/1.1 413 Payload Too Large");
  EXPECT_EQ(StatusOf(Ask(s.port(), "GET / HTTP/1.1\r\nHost: x\r\ncontent-length:  007\r\n\r\n")),
            "HTTP/1.1 413 Payload Too Large");
  EXPECT_EQ(StatusOf(Ask(s.port(), "POST / HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n")),
            "HTTP/1.1 413 Payload Too Large");
  const std::string filler(2000, 'f');
  EXPECT_EQ(StatusOf(Ask(s.port(), "GET / HTTP/1.1\r\nA: " + filler + "\r\nB: " + filler +
                                       "\r\nC: " + filler + "\r\n\r\n")),
            "HTTP/1.1 431 Request Header Fields Too Large");
  EXPECT_EQ(s.routed(), 0);
  // Within the limits: an empty body and a head just under 4 KiB reach the route.
  EXPECT_EQ(StatusOf(Ask(s.port(), "GET / HTTP/1.1\r\nAuthorization: x\r\nContent-Length: 0\r\n\r\n")),
            "HTTP/1.1 200 OK");
  EXPECT_EQ(StatusOf(Ask(s.port(), "GET / HTTP/1.1\r\nAuthorization: x\r\nA: " + filler + "\r\nB: " + filler +
                                       "\r\n\r\n")),
            "HTTP/1.1 200 OK");
  EXPECT_EQ(s.routed(), 2);
}

TEST(HttpGate, AHeadNotCompleteInTimeIsAnswered408) {
  GatedServer s(HttpLimits{.head_timeout = 300ms});
  RawConnection c(s.port());
  ASSERT_TRUE(c.Send("GET / HTTP/1.1\r\nHost: x\r\n"));
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(StatusOf(c.Receive()), "HTTP/1.1 408 Request Timeout");
  const auto waited = std::chrono::steady_clock::now() - start;
  EXPECT_GT(waited, 200ms);
  EXPECT_LT(waited, 2s);
  EXPECT_EQ(s.routed(), 0);
}

TEST(HttpGate, ANewConnectionClosesTheOneThatWaitedLongest) {
  GatedServer s(HttpLimits{.max_waiting = 2});
  RawConnection first(s.port()), second(s.port());
  ASSERT_TRUE(first.Send("GET / HTTP/1.1\r\n"));
  ASSERT_TRUE(second.Send("GET / HTTP/1.1\r\n"));
  // The third is answered; the first made room for it.
  EXPECT_EQ(StatusOf(Ask(s.port(), "GET / HTTP/1.1\r\nAuthorization: x\r\n\r\n")), "HTTP/1.1 200 OK");
  EXPECT_TRUE(first.ClosedByPeer(1));
  EXPECT_FALSE(second.ClosedByPeer(0.2));
  EXPECT_EQ(s.server().evicted(), 1u);
}

TEST(HttpGate, MoreCompleteRequestsThanTheQueueHoldsAreAnswered503) {
  std::promise<void> release;
  const std::shared_future<void> released = release.get_future().share();
  std::atomic<int> blocked{0};
  GatedServer s(HttpLimits{.max_queued = 1, .handler_threads = 1}, [&](GatedHttpServer& server) {
    server.Get("/block", [&](const httplib::Request&, httplib::Response& res) {
      ++blocked;
      released.wait_for(10s);
      res.set_content("done", "text/plain");
    });
  });
  const std::string block = "GET /block HTTP/1.1\r\nAuthorization: x\r\n\r\n";
  RawConnection busy(s.port()), queued(s.port());
  ASSERT_TRUE(busy.Send(block));
  for (int i = 0; i < 5000 && blocked == 0; ++i) std::this_thread::sleep_for(1ms);
  ASSERT_EQ(blocked, 1);
  ASSERT_TRUE(queued.Send(block));
  std::this_thread::sleep_for(100ms);  // the gate has read its head and queued it
  const std::string refused = StatusOf(Ask(s.port(), block));
  release.set_value();
  EXPECT_EQ(refused, "HTTP/1.1 503 Service Unavailable");
  EXPECT_EQ(StatusOf(busy.Receive()), "HTTP/1.1 200 OK");
  EXPECT_EQ(StatusOf(queued.Receive()), "HTTP/1.1 200 OK");
}

// A client that never reads its (authenticated, large) answer holds a handler for up to the
// write timeout, but not the coordinator's shutdown.
TEST(HttpGate, StopDoesNotWaitForAClientThatDoesNotRead) {
  std::atomic<bool> writing{false};
  GatedServer s(HttpLimits{}, [&](GatedHttpServer& server) {
    server.Get("/big", [&](const httplib::Request&, httplib::Response& res) {
      writing = true;
      res.set_content(std::string(size_t(64) << 20, 'x'), "text/plain");
    });
  });
  RawConnection reader(s.port());
  ASSERT_TRUE(reader.Send("GET /big HTTP/1.1\r\nAuthorization: x\r\n\r\n"));
  for (int i = 0; i < 5000 && !writing; ++i) std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(writing);
  std::this_thread::sleep_for(200ms);  // the socket buffers are full: the handler waits to write
  const auto start = std::chrono::steady_clock::now();
  s.server().Stop();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
}

}  // namespace
}  // namespace pf::server
