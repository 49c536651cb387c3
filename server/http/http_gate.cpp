#include "server/http/http_gate.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <poll.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <string_view>

#include "common/core/error.h"
#include "rpc/openssl_ptr.h"

namespace pf::server {

using Clock = std::chrono::steady_clock;

namespace {

std::string OpenSslErrors() {
  std::string out;
  while (const unsigned long e = ERR_get_error()) {
    char buf[256];
    ERR_error_string_n(e, buf, sizeof(buf));
    if (!out.empty()) out += "; ";
    out += buf;
  }
  return out.empty() ? "unknown error" : out;
}

BioPtr PemBio(const std::string& pem) {
  BioPtr bio = MemoryBio(pem);
  if (!bio) throw SystemError("TLS: out of memory");
  return bio;
}

// httplib's accept loop owns the queue it is given and passes every accepted socket through
// it. process_and_close_socket only hands the socket to the gate, so it runs right away on the
// accept thread: no thread of a pool is ever held by a connection that has not sent its head.
class InlineTaskQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

std::string StatusLine(int status) {
  switch (status) {
    case 408:
      return "408 Request Timeout";
    case 413:
      return "413 Payload Too Large";
    case 431:
      return "431 Request Header Fields Too Large";
    default:
      return "503 Service Unavailable";
  }
}

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

bool EqualsIgnoringCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// Waits until `fd` is ready for `events`; false once `deadline` passes or `stopping` is set (it
// is looked at every 100 ms, so a slow reader delays a shutdown by no more than that).
bool WaitFor(int fd, short events, Clock::time_point deadline, const std::atomic<bool>& stopping) {
  for (;;) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0 || stopping) return false;
    pollfd p{fd, events, 0};
    const int r = ::poll(&p, 1, int(std::min<int64_t>(left, 100)));
    if (r > 0) return true;
    if (r < 0 && errno != EINTR) return false;
  }
}

void PeerName(int fd, bool remote, std::string& ip, int& port) {
  sockaddr_storage addr{};
  socklen_t len = sizeof(addr);
  const int r = remote ? ::getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len)
                       : ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  if (r != 0) return;
  char buf[INET6_ADDRSTRLEN] = {0};
  if (addr.ss_family == AF_INET) {
    const auto* a = reinterpret_cast<const sockaddr_in*>(&addr);
    ::inet_ntop(AF_INET, &a->sin_addr, buf, sizeof(buf));
    port = ntohs(a->sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto* a = reinterpret_cast<const sockaddr_in6*>(&addr);
    ::inet_ntop(AF_INET6, &a->sin6_addr, buf, sizeof(buf));
    port = ntohs(a->sin6_port);
  }
  ip = buf;
}

}  // namespace

struct GatedHttpServer::TlsContext {
  SslCtxPtr ctx;
};

// One accepted connection: its socket (non-blocking), its TLS session, what has arrived of its
// request. Closing it closes the socket.
struct GatedConnection {
  int fd = -1;
  SslPtr ssl;               // null for plain HTTP
  bool handshaken = false;  // TLS handshake done (always true for plain HTTP)
  bool failed = false;      // a read or write failed: no close_notify
  Clock::time_point accepted;
  std::string head;  // the request line and headers, up to the blank line that ends them
  short wait_for = POLLIN;

  GatedConnection() = default;
  GatedConnection(const GatedConnection&) = delete;
  GatedConnection& operator=(const GatedConnection&) = delete;
  ~GatedConnection() {
    // close_notify for a session that was established (best effort, non-blocking).
    // Not after a fatal error (SSL_ERROR_SYSCALL or _SSL): OpenSSL forbids it, and it would only
    // leave errors behind.
    if (ssl && handshaken && !failed) {
      ERR_clear_error();
      SSL_shutdown(ssl.get());
      ERR_clear_error();
    }
    ssl.reset();
    if (fd >= 0) ::close(fd);
  }

  // What recv/SSL_read or send/SSL_write returned, as "done", "wait for an event" or "failed".
  // For TLS, SSL_ERROR_WANT_READ/WRITE set the event to wait for.
  enum class Io { kDone, kWait, kFailed };
  Io Classify(ssize_t n, short write_event) {
    if (n > 0) return Io::kDone;
    if (ssl) {
      switch (SSL_get_error(ssl.get(), int(n))) {
        case SSL_ERROR_WANT_READ:
          wait_for = POLLIN;
          return Io::kWait;
        case SSL_ERROR_WANT_WRITE:
          wait_for = POLLOUT;
          return Io::kWait;
        default:
          ERR_clear_error();
          failed = true;
          return Io::kFailed;
      }
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
      wait_for = write_event;
      return Io::kWait;
    }
    failed = true;
    return Io::kFailed;
  }
  // SSL_get_error reads this thread's OpenSSL error queue before the call's own result, and one
  // gate thread does the TLS of every connection: an error another connection left there would
  // turn this one's "want read" into a failure and drop a legitimate client. So the queue is
  // cleared before every TLS call (SSL_get_error(3), "the current thread's error queue must be
  // empty before the TLS/SSL I/O operation is attempted").
  int Handshake() {
    ERR_clear_error();
    return SSL_do_handshake(ssl.get());
  }
  ssize_t Read(char* buf, size_t size) {
    if (!ssl) return ::recv(fd, buf, size, 0);
    ERR_clear_error();
    return SSL_read(ssl.get(), buf, int(std::min<size_t>(size, 1 << 30)));
  }
  ssize_t Write(const char* buf, size_t size) {
    if (!ssl) return ::send(fd, buf, size, MSG_NOSIGNAL);
    ERR_clear_error();
    return SSL_write(ssl.get(), buf, int(std::min<size_t>(size, 1 << 30)));
  }

  // The gate's own answer: one attempt to write it without blocking, then the connection is
  // closed without reading anything more (a body in flight is never read).
  void Refuse(int status, const std::string& message) {
    if (!handshaken) return;
    const std::string response = fmt::format(
        "HTTP/1.1 {}\r\nContent-Type: text/plain\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{}\n",
        StatusLine(status), message.size() + 1, message);
    Write(response.data(), response.size());
    if (ssl) ERR_clear_error();
  }
};

namespace {

// httplib's view of a connection whose head the gate has read: reads come from that head (then
// end), writes go to the socket within the write deadline.
class GatedStream final : public httplib::Stream {
 public:
  GatedStream(GatedConnection& c, Clock::time_point write_deadline, const std::atomic<bool>& stopping)
      : c_(c), deadline_(write_deadline), stopping_(stopping) {}

  bool is_readable() const override { return read_ < c_.head.size(); }
  bool is_writable() const override { return Clock::now() < deadline_; }
  ssize_t read(char* ptr, size_t size) override {
    const size_t n = std::min(size, c_.head.size() - read_);
    std::copy_n(c_.head.data() + read_, n, ptr);
    read_ += n;
    return ssize_t(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    size_t done = 0;
    while (done < size) {
      const ssize_t n = c_.Write(ptr + done, size - done);
      switch (c_.Classify(n, POLLOUT)) {
        case GatedConnection::Io::kDone:
          done += size_t(n);
          break;
        case GatedConnection::Io::kWait:
          if (!WaitFor(c_.fd, c_.wait_for, deadline_, stopping_)) return -1;
          break;
        case GatedConnection::Io::kFailed:
          return -1;
      }
    }
    return ssize_t(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override { PeerName(c_.fd, true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { PeerName(c_.fd, false, ip, port); }
  socket_t socket() const override { return c_.fd; }

 private:
  GatedConnection& c_;
  const Clock::time_point deadline_;
  const std::atomic<bool>& stopping_;
  size_t read_ = 0;
};

}  // namespace

GatedHttpServer::GatedHttpServer(HttpLimits limits, const std::string& tls_cert_pem,
                                 const std::string& tls_key_pem)
    : limits_(limits) {
  new_task_queue = [] { return std::make_unique<InlineTaskQueue>().release(); };
  // Defence in depth: the gate refuses announced bodies, so httplib never gets to read one.
  set_payload_max_length(0);
  if (!tls_cert_pem.empty()) {
    tls_ = std::make_unique<TlsContext>();
    tls_->ctx.reset(SSL_CTX_new(TLS_server_method()));
    SSL_CTX* ctx = tls_->ctx.get();
    if (!ctx) throw SystemError("status page TLS: " + OpenSslErrors());
    SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION);
    SSL_CTX_set_mode(ctx, SSL_MODE_RELEASE_BUFFERS);  // idle waiting connections hold no buffers
    const BioPtr certs = PemBio(tls_cert_pem);
    const X509Ptr leaf = ReadPemCertificate(certs.get());
    if (!leaf || SSL_CTX_use_certificate(ctx, leaf.get()) != 1)
      throw InputError("--tls-cert: the status page cannot use the certificate: " + OpenSslErrors());
    for (X509Ptr extra = ReadPemCertificate(certs.get()); extra; extra = ReadPemCertificate(certs.get())) {
      if (SSL_CTX_add0_chain_cert(ctx, extra.get()) != 1)
        throw InputError("--tls-cert: the status page cannot use the chain: " + OpenSslErrors());
      static_cast<void>(extra.release());  // the context owns it now
    }
    ERR_clear_error();  // the loop above ends on "no start line"
    const BioPtr key_bio = PemBio(tls_key_pem);
    const PkeyPtr key = ReadPemPrivateKey(key_bio.get());
    if (!key || SSL_CTX_use_PrivateKey(ctx, key.get()) != 1 || SSL_CTX_check_private_key(ctx) != 1)
      throw InputError("--tls-key: the status page cannot use the key: " + OpenSslErrors());
  }
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_fd_ < 0) throw SystemError("status page: eventfd failed");
}

GatedHttpServer::~GatedHttpServer() {
  Stop();
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

int GatedHttpServer::Start(const std::string& host, int port) {
  int bound = port;
  if (port == 0) {
    bound = bind_to_any_port(host);
    if (bound < 0) return -1;
  } else if (!bind_to_port(host, port)) {
    return -1;
  }
  // httplib listens with a backlog of 5 (compiled into Debian's library): a burst of connections
  // (a page and its previews, or clients that never finish) overflows it and the kernel drops
  // SYNs, which clients resend only after a second. listen() again just sets a new backlog.
  ::listen(svr_sock_, SOMAXCONN);
  // OpenSSL's socket BIOs write without MSG_NOSIGNAL: a write to a peer that has reset raises
  // SIGPIPE, whose default action ends the process before any authentication. The threads that
  // write are created with SIGPIPE blocked (they inherit this thread's mask), so such a write only
  // fails with EPIPE, whatever the program's disposition of SIGPIPE (httplib::Server's constructor
  // happens to ignore it, pf-coordinator's main does too; docs/security.md "The web status page").
  sigset_t pipe, previous;
  sigemptyset(&pipe);
  sigaddset(&pipe, SIGPIPE);
  pthread_sigmask(SIG_BLOCK, &pipe, &previous);
  gate_thread_ = std::thread([this] { GateLoop(); });
  for (size_t i = 0; i < limits_.handler_threads; ++i) handlers_.emplace_back([this] { HandlerLoop(); });
  listen_thread_ = std::thread([this] { listen_after_bind(); });
  pthread_sigmask(SIG_SETMASK, &previous, nullptr);
  // httplib's stop() does nothing before its loop runs: wait for it, so that Stop() always ends it.
  const auto give_up = Clock::now() + std::chrono::seconds(5);
  while (!is_running() && Clock::now() < give_up) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return bound;
}

void GatedHttpServer::Stop() {
  if (!listen_thread_.joinable()) return;
  stop();  // closes the listening socket: the accept loop ends
  listen_thread_.join();
  {
    std::lock_guard lock(ready_mutex_);  // a handler between its check and its wait sees it
    stopping_ = true;
  }
  const uint64_t one = 1;
  [[maybe_unused]] const ssize_t w = ::write(wake_fd_, &one, sizeof(one));
  ready_cv_.notify_all();
  gate_thread_.join();
  for (std::thread& t : handlers_) t.join();
  handlers_.clear();
  ready_.clear();
  for (const socket_t fd : inbox_) ::close(fd);
  inbox_.clear();
}

bool GatedHttpServer::process_and_close_socket(socket_t sock) {
  {
    std::lock_guard lock(inbox_mutex_);
    inbox_.push_back(sock);
  }
  const uint64_t one = 1;
  [[maybe_unused]] const ssize_t w = ::write(wake_fd_, &one, sizeof(one));
  return true;
}

void GatedHttpServer::GateLoop() {
  std::deque<std::unique_ptr<GatedConnection>> waiting;  // oldest first
  std::vector<pollfd> fds;
  auto last_eviction_log = Clock::time_point{};
  uint64_t evicted_logged = 0;
  while (!stopping_) {
    fds.assign(1, pollfd{wake_fd_, POLLIN, 0});
    Clock::time_point now = Clock::now();
    int64_t timeout_ms = -1;
    for (const auto& c : waiting) {
      fds.push_back(pollfd{c->fd, c->wait_for, 0});
      const int64_t left =
          std::chrono::ceil<std::chrono::milliseconds>(c->accepted + limits_.head_timeout - now).count();
      timeout_ms =
          timeout_ms < 0 ? std::max<int64_t>(left, 0) : std::min(timeout_ms, std::max<int64_t>(left, 0));
    }
    if (::poll(fds.data(), fds.size(), int(timeout_ms)) < 0 && errno != EINTR) {
      // Stopping here would leave accepted sockets piling up in the inbox: go on.
      spdlog::error("http: poll failed (errno {})", errno);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      continue;
    }
    if (stopping_) break;
    if (fds[0].revents != 0) {
      uint64_t n = 0;
      [[maybe_unused]] const ssize_t r = ::read(wake_fd_, &n, sizeof(n));
    }
    now = Clock::now();
    std::deque<std::unique_ptr<GatedConnection>> still;
    for (size_t i = 0; i < waiting.size(); ++i) {
      std::unique_ptr<GatedConnection>& c = waiting[i];
      Step step = fds[i + 1].revents != 0 ? Advance(*c) : Step::kWait;
      if (step == Step::kWait && now >= c->accepted + limits_.head_timeout) {
        c->Refuse(408,
                  fmt::format("the request head must arrive within {} ms", limits_.head_timeout.count()));
        step = Step::kClose;
      }
      if (step == Step::kWait)
        still.push_back(std::move(c));
      else if (step == Step::kReady)
        Enqueue(std::move(c));
    }
    waiting = std::move(still);

    std::vector<socket_t> fresh;
    {
      std::lock_guard lock(inbox_mutex_);
      fresh.swap(inbox_);
    }
    for (const socket_t fd : fresh) {
      auto c = std::make_unique<GatedConnection>();
      c->fd = fd;
      c->accepted = now;
      ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
      if (tls_) {
        c->ssl.reset(SSL_new(tls_->ctx.get()));
        if (!c->ssl || SSL_set_fd(c->ssl.get(), fd) != 1) {
          ERR_clear_error();
          continue;  // c closes the socket
        }
        SSL_set_accept_state(c->ssl.get());
      } else {
        c->handshaken = true;
      }
      if (waiting.size() >= limits_.max_waiting) {
        waiting.pop_front();  // the longest wait; a live client's head takes milliseconds
        ++evicted_;
      }
      waiting.push_back(std::move(c));
    }
    if (evicted_ > evicted_logged && now - last_eviction_log > std::chrono::seconds(10)) {
      spdlog::warn(
          "http: {} connections closed so far to make room: {} were waiting for their request head (slow or "
          "hostile clients?)",
          evicted_.load(), limits_.max_waiting);
      evicted_logged = evicted_;
      last_eviction_log = now;
    }
  }
}

GatedHttpServer::Step GatedHttpServer::Advance(GatedConnection& c) {
  if (!c.handshaken) {
    const int r = c.Handshake();
    if (r != 1) {
      // Not TLS, or a client that does not trust the certificate: nothing to answer.
      return c.Classify(r, POLLOUT) == GatedConnection::Io::kWait ? Step::kWait : Step::kClose;
    }
    c.handshaken = true;
  }
  char buf[4096];
  for (;;) {
    // One byte more than allowed tells a head that is too large.
    const size_t room = limits_.max_head_bytes + 1 - c.head.size();
    const ssize_t n = c.Read(buf, std::min(sizeof(buf), room));
    switch (c.Classify(n, POLLIN)) {
      case GatedConnection::Io::kWait:
        return Step::kWait;
      case GatedConnection::Io::kFailed:
        return Step::kClose;
      case GatedConnection::Io::kDone:
        break;
    }
    const size_t from = c.head.size() >= 3 ? c.head.size() - 3 : 0;
    c.head.append(buf, size_t(n));
    const size_t end = c.head.find("\r\n\r\n", from);
    if (end != std::string::npos && end + 4 <= limits_.max_head_bytes) return Judge(c, end + 4);
    if (c.head.size() > limits_.max_head_bytes || end != std::string::npos) {
      c.Refuse(431, fmt::format("the request line and headers must fit in {} bytes", limits_.max_head_bytes));
      return Step::kClose;
    }
  }
}

GatedHttpServer::Step GatedHttpServer::Judge(GatedConnection& c, size_t head_end) {
  const std::string_view head(c.head.data(), head_end);
  for (size_t line = head.find("\r\n") + 2; line < head_end;) {
    const size_t eol = head.find("\r\n", line);
    const std::string_view header = head.substr(line, eol - line);
    line = eol + 2;
    const size_t colon = header.find(':');
    if (colon == std::string_view::npos) continue;
    const std::string_view name = Trim(header.substr(0, colon)), value = Trim(header.substr(colon + 1));
    if (EqualsIgnoringCase(name, "Transfer-Encoding") ||
        (EqualsIgnoringCase(name, "Content-Length") &&
         value.find_first_not_of('0') != std::string_view::npos)) {
      c.Refuse(413, "this page takes no request body");
      return Step::kClose;
    }
  }
  c.head.resize(head_end);  // anything after the head is never read: one request per connection
  return Step::kReady;
}

void GatedHttpServer::Enqueue(std::unique_ptr<GatedConnection> c) {
  {
    std::lock_guard lock(ready_mutex_);
    if (ready_.size() < limits_.max_queued) {
      ready_.push_back(std::move(c));
      ready_cv_.notify_one();
      return;
    }
  }
  c->Refuse(503, "too many requests at once; try again");
}

void GatedHttpServer::HandlerLoop() {
  for (;;) {
    std::unique_ptr<GatedConnection> c;
    {
      std::unique_lock lock(ready_mutex_);
      ready_cv_.wait(lock, [&] { return stopping_ || !ready_.empty(); });
      if (stopping_) return;
      c = std::move(ready_.front());
      ready_.pop_front();
    }
    Serve(*c);
  }
}

void GatedHttpServer::Serve(GatedConnection& c) {
  GatedStream stream(c, Clock::now() + limits_.write_timeout, stopping_);
  bool closed = false;
  try {
    process_request(stream, /*close_connection=*/true, closed, nullptr);
  } catch (const std::exception& e) {  // httplib catches the routes' exceptions, not its own
    spdlog::warn("http: request failed: {}", e.what());
  }
}

}  // namespace pf::server
