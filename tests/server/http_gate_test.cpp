// The status page's gate (server/http/http_gate.h) in-process, with small limits so that each
// rule shows in milliseconds: what it answers by itself (408, 413, 431, 503) never reaches a
// route, and a new connection makes room by closing the one that waited longest. The farm-level
// view (a real coordinator, 400 MiB bodies, 200 slow clients, HTTPS) is in
// tests/e2e/web_status_test.cpp and tests/e2e/security_test.cpp.
#include "server/http/http_gate.h"

#include <gtest/gtest.h>
#include <netinet/in.h>
#include <openssl/ec.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
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
  explicit GatedServer(HttpLimits limits, const std::function<void(GatedHttpServer&)>& more = {},
                       const std::string& tls_cert_pem = "", const std::string& tls_key_pem = "")
      : server_(limits, tls_cert_pem, tls_key_pem) {
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

// A self-signed certificate for "localhost" and its key, made in memory (the test client does not
// verify it: what is under test is the server side of the connection).
struct SelfSigned {
  std::string cert_pem, key_pem;
};

std::string PemOf(const std::function<int(BIO*)>& write) {
  BIO* bio = BIO_new(BIO_s_mem());
  EXPECT_EQ(write(bio), 1);
  char* data = nullptr;
  const long size = BIO_get_mem_data(bio, &data);
  std::string pem(data, size_t(size));
  BIO_free(bio);
  return pem;
}

SelfSigned MakeSelfSigned() {
  EVP_PKEY* key = EVP_EC_gen("P-256");
  X509* cert = X509_new();
  X509_set_version(cert, 2);
  ASN1_INTEGER_set(X509_get_serialNumber(cert), 1);
  X509_gmtime_adj(X509_getm_notBefore(cert), -60);
  X509_gmtime_adj(X509_getm_notAfter(cert), 3600);
  X509_set_pubkey(cert, key);
  X509_NAME* name = X509_get_subject_name(cert);
  X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC, reinterpret_cast<const unsigned char*>("localhost"),
                             -1, -1, 0);
  X509_set_issuer_name(cert, name);
  X509_sign(cert, key, EVP_sha256());
  SelfSigned out{PemOf([&](BIO* b) { return PEM_write_bio_X509(b, cert); }), PemOf([&](BIO* b) {
                   return PEM_write_bio_PrivateKey(b, key, nullptr, nullptr, 0, nullptr, nullptr);
                 })};
  X509_free(cert);
  EVP_PKEY_free(key);
  return out;
}

// A TLS client on a blocking socket to 127.0.0.1:PORT that trusts anything.
class TlsClient {
 public:
  explicit TlsClient(int port)
      : ctx_(SSL_CTX_new(TLS_client_method())), fd_(::socket(AF_INET, SOCK_STREAM, 0)) {
    if (!test_util::ConnectToLoopback(fd_, port)) return;
    ssl_ = SSL_new(ctx_);
    SSL_set_fd(ssl_, fd_);
    connected_ = SSL_connect(ssl_) == 1;
  }
  ~TlsClient() {
    if (ssl_) SSL_free(ssl_);
    SSL_CTX_free(ctx_);
    if (fd_ >= 0) ::close(fd_);
    ERR_clear_error();
  }
  TlsClient(const TlsClient&) = delete;
  TlsClient& operator=(const TlsClient&) = delete;

  bool connected() const { return connected_; }
  bool Send(const std::string& bytes) {
    return SSL_write(ssl_, bytes.data(), int(bytes.size())) == int(bytes.size());
  }
  std::string Receive() {
    std::string out;
    char buf[4096];
    for (int n; (n = SSL_read(ssl_, buf, sizeof(buf))) > 0;) out.append(buf, size_t(n));
    return out;
  }
  // Closes the socket with a TCP reset (SO_LINGER 0), as a client that crashes or gives up does.
  void Reset() {
    const linger abort{1, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &abort, sizeof(abort));
    ::close(fd_);
    fd_ = -1;
  }

 private:
  SSL_CTX* ctx_;
  SSL* ssl_ = nullptr;
  int fd_;
  bool connected_ = false;
};

// A client that completes the handshake, sends a request and resets the connection before the
// answer: writing to the reset socket (OpenSSL's socket BIOs send without MSG_NOSIGNAL) must not
// raise SIGPIPE, whose default action ends the whole process (docs/security.md, "The web status
// page"). Both writers are tried: the gate itself (a 413 before authentication) and a handler
// (a route's answer). Without the fix this test binary dies of SIGPIPE.
TEST(HttpGate, OverTlsAPeerThatResetsDoesNotKillTheProcess) {
  const SelfSigned cert = MakeSelfSigned();
  std::promise<void> reset_done;
  const std::shared_future<void> reset = reset_done.get_future().share();
  std::atomic<int> blocked{0}, answered{0};
  GatedServer s(
      HttpLimits{},
      [&](GatedHttpServer& server) {
        server.Get("/block", [&](const httplib::Request&, httplib::Response& res) {
          ++blocked;
          reset.wait_for(10s);
          res.set_content(std::string(size_t(1) << 20, 'x'), "text/plain");
          ++answered;
        });
      },
      cert.cert_pem, cert.key_pem);
  ASSERT_GT(s.port(), 0);
  ASSERT_TRUE(s.server().tls());
  // httplib::Server's constructor ignores SIGPIPE for the whole process (Debian's 0.11 does): the
  // gate must not depend on that, nor on its program doing it.
  const auto previous = std::signal(SIGPIPE, SIG_DFL);

  {  // The route answers a peer that has gone.
    TlsClient c(s.port());
    ASSERT_TRUE(c.connected());
    ASSERT_TRUE(c.Send("GET /block HTTP/1.1\r\nAuthorization: x\r\n\r\n"));
    for (int i = 0; i < 5000 && blocked == 0; ++i) std::this_thread::sleep_for(1ms);
    ASSERT_EQ(blocked, 1);
    c.Reset();
    std::this_thread::sleep_for(50ms);  // the reset reaches the server side before the answer
    reset_done.set_value();
  }
  for (int i = 0; i < 5000 && answered == 0; ++i) std::this_thread::sleep_for(1ms);
  ASSERT_EQ(answered, 1);

  // The gate reads part of a head, then the reset (which its read reports), then closes the
  // session, which writes close_notify to the reset socket; or it refuses (413) a peer that has
  // gone.
  for (const char* head : {"GET / HTTP/1.1\r\nHost: x\r\n", "GET / HTTP/1.1\r\nContent-Length: 5\r\n\r\n"}) {
    for (int i = 0; i < 10; ++i) {
      TlsClient c(s.port());
      ASSERT_TRUE(c.connected());
      ASSERT_TRUE(c.Send(head));
      c.Reset();
    }
  }
  // Still serving, over TLS.
  TlsClient after(s.port());
  ASSERT_TRUE(after.connected());
  ASSERT_TRUE(after.Send("GET / HTTP/1.1\r\nAuthorization: x\r\n\r\n"));
  EXPECT_EQ(StatusOf(after.Receive()), "HTTP/1.1 200 OK");
  std::signal(SIGPIPE, previous);
}

// One gate thread does the TLS of every connection, and OpenSSL's error queue is per thread:
// what one connection's failure leaves there must not turn another's "wait for more input" into a
// failure (SSL_get_error looks at the queue first). A client that handshakes and closes without
// close_notify leaves such errors behind; a client whose head is still arriving must be served.
TEST(HttpGate, OverTlsOneConnectionsErrorsDoNotFailAnother) {
  const SelfSigned cert = MakeSelfSigned();
  GatedServer s(HttpLimits{}, {}, cert.cert_pem, cert.key_pem);
  ASSERT_GT(s.port(), 0);
  int served = 0;
  for (int i = 0; i < 10; ++i) {
    TlsClient waiting(s.port());
    ASSERT_TRUE(waiting.connected());
    ASSERT_TRUE(waiting.Send("GET / HTTP/1.1\r\n"));
    {
      TlsClient gone(s.port());
      ASSERT_TRUE(gone.connected());
    }  // closed: the gate reads an unexpected end of file, then closes the session
    std::this_thread::sleep_for(20ms);  // for the gate to get there first
    if (waiting.Send("Authorization: x\r\n") && waiting.Send("\r\n") &&
        StatusOf(waiting.Receive()) == "HTTP/1.1 200 OK")
      ++served;
  }
  EXPECT_EQ(served, 10);
  EXPECT_EQ(s.routed(), 10);
}

}  // namespace
}  // namespace pf::server
