#include "rpc/tls_diagnosis.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509v3.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <memory>
#include <vector>

#include "rpc/openssl_ptr.h"

namespace pf {
namespace {

using Clock = std::chrono::steady_clock;

struct AddrinfoFree {
  void operator()(addrinfo* p) const { freeaddrinfo(p); }
};

class Socket {
 public:
  explicit Socket(int fd) : fd_(fd) {}
  ~Socket() {
    if (fd_ >= 0) ::close(fd_);
  }
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;
  int fd() const { return fd_; }

 private:
  int fd_;
};

// OpenSSL's socket BIOs write without MSG_NOSIGNAL: a write to a coordinator that has reset
// raises SIGPIPE, whose default action ends pf with 141 instead of an error. pf keeps that default
// (so that `pf watch --json | head -1` ends), so SIGPIPE is blocked on this thread while the
// diagnosis runs, and one it raised is taken back before the mask is restored.
class SigpipeBlocked {
 public:
  SigpipeBlocked() {
    sigemptyset(&pipe_);
    sigaddset(&pipe_, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_, &previous_);
    sigset_t pending;
    sigpending(&pending);
    was_pending_ = sigismember(&pending, SIGPIPE) == 1;
  }
  ~SigpipeBlocked() {
    sigset_t pending;
    sigpending(&pending);
    if (!was_pending_ && sigismember(&pending, SIGPIPE) == 1) {
      const timespec now{0, 0};
      while (sigtimedwait(&pipe_, nullptr, &now) < 0 && errno == EINTR) {
      }
    }
    pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
  }
  SigpipeBlocked(const SigpipeBlocked&) = delete;
  SigpipeBlocked& operator=(const SigpipeBlocked&) = delete;

 private:
  sigset_t pipe_, previous_;
  bool was_pending_ = false;
};

// HOST and PORT of "HOST:PORT", "[V6]:PORT", "dns:///HOST:PORT", "ipv4:..."; false for unix: targets.
bool SplitAddress(std::string a, std::string* host, std::string* port) {
  if (a.rfind("unix:", 0) == 0 || a.rfind("unix-abstract:", 0) == 0) return false;
  for (const char* prefix : {"dns:///", "ipv4:", "ipv6:"})
    if (a.rfind(prefix, 0) == 0) a = a.substr(std::strlen(prefix));
  const size_t colon = a.rfind(':');
  if (colon == std::string::npos) return false;
  *host = a.substr(0, colon);
  *port = a.substr(colon + 1);
  if (host->size() >= 2 && host->front() == '[' && host->back() == ']')
    *host = host->substr(1, host->size() - 2);
  return !host->empty() && !port->empty();
}

bool WaitFor(int fd, short events, Clock::time_point deadline) {
  for (;;) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return false;
    pollfd p{fd, events, 0};
    const int r = ::poll(&p, 1, int(left));
    if (r > 0) return true;
    if (r < 0 && errno != EINTR) return false;
  }
}

// A connected non-blocking TCP socket, or -1.
int Connect(const std::string& host, const std::string& port, Clock::time_point deadline) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (::getaddrinfo(host.c_str(), port.c_str(), &hints, &found) != 0) return -1;
  const std::unique_ptr<addrinfo, AddrinfoFree> list(found);
  for (const addrinfo* ai = list.get(); ai != nullptr; ai = ai->ai_next) {
    const int fd = ::socket(ai->ai_family, ai->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, ai->ai_protocol);
    if (fd < 0) continue;
    int error = 0;
    socklen_t len = sizeof(error);
    if ((::connect(fd, ai->ai_addr, ai->ai_addrlen) == 0 ||
         (errno == EINPROGRESS && WaitFor(fd, POLLOUT, deadline) &&
          ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &len) == 0 && error == 0)))
      return fd;
    ::close(fd);
  }
  return -1;
}

std::string Date(const ASN1_TIME* t) {
  std::tm tm{};
  if (ASN1_TIME_to_tm(t, &tm) != 1) return "?";
  char buf[64];
  std::strftime(buf, sizeof(buf), "%Y-%m-%d %H:%M:%S UTC", &tm);
  return buf;
}

std::string NameOf(const X509_NAME* name) {
  const BioPtr bio(BIO_new(BIO_s_mem()));
  if (!bio || X509_NAME_print_ex(bio.get(), name, 0, XN_FLAG_RFC2253) < 0) return "?";
  char* data = nullptr;
  const long size = BIO_get_mem_data(bio.get(), &data);
  std::string quoted = "'";
  quoted.append(data, size_t(std::max(0L, size)));
  quoted += '\'';
  return quoted;
}

std::vector<X509Ptr> ReadCertificates(const std::string& pem) {
  std::vector<X509Ptr> certs;
  const BioPtr bio = MemoryBio(pem);
  if (!bio) return certs;
  for (X509Ptr c = ReadPemCertificate(bio.get()); c; c = ReadPemCertificate(bio.get()))
    certs.push_back(std::move(c));
  ERR_clear_error();  // the loop ends on "no start line"
  return certs;
}

// What this client's own certificate tells about a refusal: its dates, and whether its issuer is
// one of the CAs the coordinator named as acceptable in its certificate request (gRPC sends the
// names of its --tls-client-ca). "" when nothing looks wrong.
std::string OwnCertificateProblem(const ClientTls& tls, const SSL* ssl) {
  const std::vector<X509Ptr> chain = ReadCertificates(tls.cert_pem);
  if (chain.empty()) return "";
  const X509* leaf = chain.front().get();
  if (X509_cmp_current_time(X509_get0_notAfter(leaf)) < 0)
    return "it expired on " + Date(X509_get0_notAfter(leaf)) + " (renew --tls-cert)";
  if (X509_cmp_current_time(X509_get0_notBefore(leaf)) > 0)
    return "it is not valid before " + Date(X509_get0_notBefore(leaf));
  const STACK_OF(X509_NAME)* accepted = ssl ? SSL_get0_peer_CA_list(ssl) : nullptr;
  if (accepted == nullptr || sk_X509_NAME_num(accepted) == 0) return "";
  std::string names;
  for (int i = 0; i < sk_X509_NAME_num(accepted); ++i) {
    const X509_NAME* ca = sk_X509_NAME_value(accepted, i);
    for (const X509Ptr& c : chain)
      if (X509_NAME_cmp(X509_get_issuer_name(c.get()), ca) == 0) return "";
    names += (names.empty() ? "" : ", ") + NameOf(ca);
  }
  return "it is signed by " + NameOf(X509_get_issuer_name(leaf)) +
         ", another CA than the one the coordinator accepts (" + names + ", its --tls-client-ca)";
}

// How a handshake or the first read ended.
struct Outcome {
  enum Kind { kOk, kTimeout, kAlert, kUntrusted, kNotTls, kClosed, kOther };
  explicit Outcome(Kind k = kOk, int a = 0, long v = 0) : kind(k), alert(a), verify(v) {}
  Kind kind;
  int alert;           // kAlert: the TLS alert the coordinator sent
  long verify;         // kUntrusted: X509_V_ERR_*
  std::string detail;  // kOther: OpenSSL's words
};

// Runs `op` (a handshake or a read) on the non-blocking `ssl` until it succeeds, fails or the
// deadline passes, and says how it ended.
template <typename Op>
Outcome Drive(SSL* ssl, int fd, Clock::time_point deadline, Op op) {
  for (;;) {
    ERR_clear_error();
    errno = 0;
    const int r = op();
    if (r > 0) return Outcome();
    const int e = SSL_get_error(ssl, r);
    if (e == SSL_ERROR_WANT_READ || e == SSL_ERROR_WANT_WRITE) {
      if (!WaitFor(fd, e == SSL_ERROR_WANT_READ ? POLLIN : POLLOUT, deadline))
        return Outcome(Outcome::kTimeout);
      continue;
    }
    Outcome out(Outcome::kOther);
    for (unsigned long err = ERR_get_error(); err != 0; err = ERR_get_error()) {
      if (ERR_GET_LIB(err) != ERR_LIB_SSL) continue;
      const int reason = ERR_GET_REASON(err);
      if (reason > SSL_AD_REASON_OFFSET) {
        out = Outcome(Outcome::kAlert, reason - SSL_AD_REASON_OFFSET);
      } else if (reason == SSL_R_CERTIFICATE_VERIFY_FAILED) {
        out = Outcome(Outcome::kUntrusted, 0, SSL_get_verify_result(ssl));
      } else if (reason == SSL_R_WRONG_VERSION_NUMBER || reason == SSL_R_PACKET_LENGTH_TOO_LONG ||
                 reason == SSL_R_HTTP_REQUEST) {
        out = Outcome(Outcome::kNotTls);
      } else if (reason == SSL_R_UNEXPECTED_EOF_WHILE_READING) {
        out = Outcome(Outcome::kClosed);
      } else if (out.kind == Outcome::kOther) {
        char buf[256];
        ERR_error_string_n(err, buf, sizeof(buf));
        out.detail = buf;
      }
    }
    if (out.kind == Outcome::kOther && out.detail.empty())
      out.kind = e == SSL_ERROR_ZERO_RETURN || (e == SSL_ERROR_SYSCALL && errno == 0) ? Outcome::kClosed
                                                                                      : Outcome::kOther;
    if (out.kind == Outcome::kOther && out.detail.empty())
      out.detail = e == SSL_ERROR_SYSCALL ? std::strerror(errno) : "SSL error " + std::to_string(e);
    return out;
  }
}

bool IsCertificateAlert(int alert) {
  switch (alert) {
    case SSL_AD_BAD_CERTIFICATE:
    case SSL_AD_UNSUPPORTED_CERTIFICATE:
    case SSL_AD_CERTIFICATE_REVOKED:
    case SSL_AD_CERTIFICATE_EXPIRED:
    case SSL_AD_CERTIFICATE_UNKNOWN:
    case SSL_AD_UNKNOWN_CA:
    case SSL_AD_ACCESS_DENIED:
    case SSL_AD_DECRYPT_ERROR:
      return true;
    default:
      return false;
  }
}

// The sentence after "TLS handshake with ADDRESS failed: ", or "" when `out` explains nothing.
// `ssl` is the session after a completed handshake, else null.
std::string Explain(const Outcome& out, const ClientTls& tls, const std::string& name, const SSL* ssl) {
  const std::string own = OwnCertificateProblem(tls, ssl);
  const std::string refused = "the coordinator refused this client's certificate";
  switch (out.kind) {
    case Outcome::kOk:
    case Outcome::kTimeout:
      return "";
    case Outcome::kAlert: {
      const std::string alert = std::string("alert \"") + SSL_alert_desc_string_long(out.alert) + "\"";
      if (out.alert == SSL_AD_CERTIFICATE_REQUIRED || (tls.cert_pem.empty() && IsCertificateAlert(out.alert)))
        return "the coordinator requires a client certificate (" + alert + "): pass --tls-cert/--tls-key";
      if (!IsCertificateAlert(out.alert)) return "the coordinator ended the handshake with " + alert;
      if (!own.empty()) return refused + " (" + alert + "): " + own;
      if (out.alert == SSL_AD_UNKNOWN_CA)
        return refused + " (" + alert +
               "): it is not signed by a CA the coordinator trusts (another CA? its --tls-client-ca decides)";
      return refused + " (" + alert + "; expired? another CA?)";
    }
    case Outcome::kUntrusted:
      if (out.verify == X509_V_ERR_HOSTNAME_MISMATCH || out.verify == X509_V_ERR_IP_ADDRESS_MISMATCH)
        return "the coordinator's certificate does not name " + name +
               " (connect with a name or address its subjectAltName lists)";
      return std::string("this client does not trust the coordinator's certificate: ") +
             X509_verify_cert_error_string(out.verify) + " (is --tls-ca the CA that signed it?)";
    case Outcome::kNotTls:
      return "the coordinator does not answer TLS on this port (a plaintext coordinator? then drop --tls-ca)";
    case Outcome::kClosed:
      if (ssl == nullptr)
        return "the coordinator closed the connection during the handshake (a plaintext coordinator? then "
               "drop "
               "--tls-ca)";
      // gRPC's server judges the certificate after the handshake and closes without an alert.
      if (tls.cert_pem.empty()) return "the coordinator closed the connection right after the handshake";
      if (!own.empty()) return refused + " (it closed the connection after the handshake): " + own;
      return refused + " (it closed the connection right after the handshake; expired? another CA?)";
    case Outcome::kOther:
      return "TLS error: " + out.detail;
  }
  return "";
}

SslCtxPtr ClientContext(const ClientTls& tls) {
  SslCtxPtr ctx(SSL_CTX_new(TLS_client_method()));
  if (!ctx) return nullptr;
  SSL_CTX_set_verify(ctx.get(), SSL_VERIFY_PEER, nullptr);
  const BioPtr roots = MemoryBio(tls.ca_pem);
  X509_STORE* store = SSL_CTX_get_cert_store(ctx.get());
  for (X509Ptr ca = ReadPemCertificate(roots.get()); ca; ca = ReadPemCertificate(roots.get()))
    X509_STORE_add_cert(store, ca.get());
  if (!tls.cert_pem.empty()) {
    const BioPtr certs = MemoryBio(tls.cert_pem);
    const X509Ptr leaf = ReadPemCertificate(certs.get());
    if (!leaf || SSL_CTX_use_certificate(ctx.get(), leaf.get()) != 1) return nullptr;
    for (X509Ptr extra = ReadPemCertificate(certs.get()); extra; extra = ReadPemCertificate(certs.get()))
      if (SSL_CTX_add0_chain_cert(ctx.get(), extra.get()) == 1) static_cast<void>(extra.release());
    const BioPtr key_bio = MemoryBio(tls.key_pem);
    const PkeyPtr key = ReadPemPrivateKey(key_bio.get());
    if (!key || SSL_CTX_use_PrivateKey(ctx.get(), key.get()) != 1) return nullptr;
  }
  ERR_clear_error();
  return ctx;
}

}  // namespace

std::string DiagnoseTlsHandshake(const std::string& address, const ClientTls& tls,
                                 std::chrono::milliseconds timeout) {
  std::string host, port;
  if (tls.ca_pem.empty() || !SplitAddress(address, &host, &port)) return "";
  const Clock::time_point deadline = Clock::now() + timeout;
  const SigpipeBlocked no_sigpipe;  // before the socket: it is closed while SIGPIPE is blocked
  const Socket socket(Connect(host, port, deadline));
  if (socket.fd() < 0) return "";
  const auto ctx = ClientContext(tls);
  if (!ctx) return "";
  const SslPtr ssl(SSL_new(ctx.get()));
  if (!ssl || SSL_set_fd(ssl.get(), socket.fd()) != 1) return "";
  SSL_set_connect_state(ssl.get());
  // What gRPC checks: the server name (or the override) against the certificate, ALPN h2.
  const std::string name = tls.server_name.empty() ? host : tls.server_name;
  in6_addr ip{};
  if (::inet_pton(AF_INET, name.c_str(), &ip) == 1 || ::inet_pton(AF_INET6, name.c_str(), &ip) == 1) {
    X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(ssl.get()), name.c_str());
  } else {
    SSL_set_tlsext_host_name(ssl.get(), name.c_str());
    SSL_set1_host(ssl.get(), name.c_str());
  }
  static constexpr unsigned char kAlpnH2[] = {2, 'h', '2'};
  SSL_set_alpn_protos(ssl.get(), kAlpnH2, sizeof(kAlpnH2));

  const std::string prefix = "TLS handshake with " + address + " failed: ";
  Outcome out = Drive(ssl.get(), socket.fd(), deadline, [&] { return SSL_do_handshake(ssl.get()); });
  if (out.kind != Outcome::kOk) {
    const std::string why = Explain(out, tls, name, nullptr);
    return why.empty() ? "" : prefix + why;
  }
  // With TLS 1.3 the coordinator judges our certificate after our side is done: its first
  // answer is its HTTP/2 settings if it accepted us, an alert if not.
  char byte = 0;
  out = Drive(ssl.get(), socket.fd(), deadline, [&] { return SSL_read(ssl.get(), &byte, 1); });
  const std::string why = Explain(out, tls, name, ssl.get());
  return why.empty() ? "" : prefix + why;
}

grpc::Status ExplainTlsFailure(const grpc::Status& status, const std::string& address, const ClientTls& tls) {
  if (status.error_code() != grpc::StatusCode::UNAVAILABLE || tls.ca_pem.empty()) return status;
  const std::string why = DiagnoseTlsHandshake(address, tls);
  return why.empty() ? status : grpc::Status(grpc::StatusCode::UNAVAILABLE, why);
}

}  // namespace pf
