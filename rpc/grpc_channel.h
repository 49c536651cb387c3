#pragma once
// The client side of every connection to the coordinator: `pf`, `pf-worker` and the e2e tests
// all open their channels here, so keepalive, reconnect backoff, message limits, TLS, the bearer
// token and deadlines are configured in one place (the coordinator parses its tokens here too)
// (docs/design.md, G5; every client call has a deadline, keepalive on both sides).
//
// Keepalive: a ping every 10 s even without calls (so an idle worker long-polling a coordinator
// that vanished without closing its sockets notices within ~15 s); the coordinator permits
// pings at that rate. Reconnect backoff is capped at 2 s (gRPC's default cap is 120 s), so a
// restarted coordinator is found quickly (a closed port refuses at once); the worker adds its own
// jittered backoff on top. One connection attempt may take up to 20 s (grpc_channel.cpp says why).

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>

namespace pf {

// A failed RPC as an exception, for code paths that report errors by throwing (the CLI, the
// worker's scene fetcher). what() is StatusToString(status).
class RpcError : public std::runtime_error {
 public:
  explicit RpcError(grpc::Status status);
  const grpc::Status& status() const { return status_; }
  grpc::StatusCode code() const { return status_.error_code(); }

 private:
  grpc::Status status_;
};

// TLS towards the coordinator (docs/security.md). ca_pem empty = plaintext.
struct ClientTls {
  std::string ca_pem;       // PEM roots that sign the coordinator's certificate; non-empty = TLS
  std::string cert_pem;     // client certificate chain (mTLS, workers); "" = none
  std::string key_pem;      // its private key
  std::string server_name;  // name to verify instead of the address' host ("" = the host)
};

// Reads the PEM files named by the --tls-ca / --tls-cert / --tls-key flags (each may be "",
// falling back to $PF_TLS_CA / $PF_TLS_CERT / $PF_TLS_KEY). InputError if a file cannot be
// read, if cert and key come alone, or if a client certificate is given without a CA.
ClientTls ResolveClientTls(std::string ca_file, std::string cert_file, std::string key_file);

struct ChannelOptions {
  std::string token;         // bearer token; "" = none
  ClientTls tls;             // plaintext unless tls.ca_pem is set
  int keepalive_ms = 10000;  // 0 = no keepalive pings
  int keepalive_timeout_ms = 5000;
  int max_reconnect_backoff_ms = 2000;
};

// A channel to HOST:PORT with the options above: TLS when options.tls.ca_pem is set, else
// plaintext.
std::shared_ptr<grpc::Channel> MakeCoordinatorChannel(const std::string& address,
                                                      const ChannelOptions& options);

// A bearer token from untrusted text (a file or an environment variable named by `source`):
// surrounding whitespace (a trailing newline) is trimmed; what remains must be non-empty, one
// line of printable ASCII without spaces (it goes into an HTTP/2 header; a newline there would
// abort gRPC) and at most 4096 bytes. Anything else is an InputError naming `source`.
std::string ParseToken(std::string_view text, const std::string& source);

// The bearer token: the whole of `token_file` if given, else of the file $`file_env_name` names
// if that is set (nullptr: not looked at), else $`env_name` if set (set but blank is an error, not
// "no token"), else "". Parsed with ParseToken; InputError if unreadable.
std::string ResolveToken(const std::string& token_file, const char* env_name = "PF_TOKEN",
                         const char* file_env_name = "PF_TOKEN_FILE");

// Sets a deadline `timeout` from now and, if `token` is non-empty, the
// "authorization: Bearer <token>" metadata.
void PrepareContext(grpc::ClientContext* context, const std::string& token,
                    std::chrono::milliseconds timeout);

inline std::chrono::milliseconds Seconds(double s) {
  return std::chrono::milliseconds(int64_t(s * 1000.0));
}

// "CODE: message" for logs and CLI errors, e.g. "INVALID_ARGUMENT: spec.camera.width/height: must be > 0".
std::string StatusToString(const grpc::Status& status);
const char* StatusCodeName(grpc::StatusCode code);

}  // namespace pf
