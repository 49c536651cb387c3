#pragma once
// The front door of the web status page (docs/security.md, "The web status page"). cpp-httplib
// parses requests and runs the routes, but on its own it reads a request's line and headers with
// no limit on their size or on the time they take, one of its few threads held per connection
// meanwhile: three slow clients made the page unreachable, and a 400 MiB body sent after a 401
// was read as the next request line, into memory. So no connection reaches httplib before its
// whole head has arrived:
//
//   httplib's accept loop → process_and_close_socket hands the socket to the gate thread (it
//   never blocks) → the gate thread reads the TLS handshake and the head of every waiting
//   connection at once, with poll() on non-blocking sockets, at most max_head_bytes within
//   head_timeout of the accept → a complete head is queued for a handler thread, which lets
//   httplib parse it from memory and answer: authentication, routes, the response (written
//   within write_timeout). One request per connection (Connection: close).
//
// The gate answers by itself, before authentication and without reading any further: a head
// larger than the limit (431), a request that announces a body (Content-Length other than 0, or a
// Transfer-Encoding; no route takes one: 413), a head not complete in time (408), a full handler
// queue (503). At most max_waiting connections wait for their head; a new one closes the one that
// has waited longest, so clients that never finish their head cannot keep a new one out.

#include <httplib.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace pf::server {

struct HttpLimits {
  // Request line and headers together; browsers send well under 2 KiB.
  size_t max_head_bytes = 16 * 1024;
  // From the accept to the end of the head, TLS handshake included; a browser needs milliseconds.
  std::chrono::milliseconds head_timeout{5000};
  // For writing a whole response (the largest are preview PNGs). Stop() does not wait for it.
  std::chrono::milliseconds write_timeout{30000};
  // Connections whose head has not arrived yet (each holds a socket and ≤ max_head_bytes).
  size_t max_waiting = 128;
  // Complete requests waiting for a handler thread.
  size_t max_queued = 64;
  // The page is for people: a few requests a second at most.
  size_t handler_threads = 2;
};

struct GatedConnection;

class GatedHttpServer : public httplib::Server {
 public:
  // With `tls_cert_pem` (and its key) the server speaks HTTPS with that certificate chain, else
  // plain HTTP. InputError if the certificate or key does not load.
  explicit GatedHttpServer(HttpLimits limits, const std::string& tls_cert_pem = "",
                           const std::string& tls_key_pem = "");
  ~GatedHttpServer() override;  // Stop()
  GatedHttpServer(const GatedHttpServer&) = delete;
  GatedHttpServer& operator=(const GatedHttpServer&) = delete;

  // Binds HOST:PORT (port 0: a free port) and serves on its own threads. Returns the bound port,
  // or -1 if the address cannot be bound.
  int Start(const std::string& host, int port);
  void Stop();  // idempotent

  bool tls() const { return tls_ != nullptr; }
  const HttpLimits& limits() const { return limits_; }
  // Connections closed to make room for a new one (max_waiting were waiting for their head).
  uint64_t evicted() const { return evicted_; }

 private:
  struct TlsContext;
  enum class Step { kWait, kReady, kClose };

  // httplib's accept loop hands every accepted socket here (on the accept thread).
  bool process_and_close_socket(socket_t sock) override;
  void GateLoop();
  Step Advance(GatedConnection& connection);
  Step Judge(GatedConnection& connection, size_t head_end);
  void Enqueue(std::unique_ptr<GatedConnection> connection);
  void HandlerLoop();
  void Serve(GatedConnection& connection);

  const HttpLimits limits_;
  std::unique_ptr<TlsContext> tls_;
  int wake_fd_ = -1;  // eventfd: new sockets in inbox_, or stopping_

  std::mutex inbox_mutex_;
  std::vector<socket_t> inbox_;

  std::mutex ready_mutex_;
  std::condition_variable ready_cv_;
  std::deque<std::unique_ptr<GatedConnection>> ready_;

  std::atomic<bool> stopping_{false};
  std::atomic<uint64_t> evicted_{0};
  std::thread listen_thread_, gate_thread_;
  std::vector<std::thread> handlers_;
};

}  // namespace pf::server
