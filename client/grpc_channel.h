#pragma once
// The client side of every connection to the coordinator: `pf`, `pf-worker` and the e2e tests
// all open their channels here, so keepalive, reconnect backoff, message limits, the bearer
// token and deadlines are configured in one place (docs/design.md, G5; every client call
// has a deadline, keepalive on both sides).
//
// Keepalive: a ping every 10 s even without calls (so an idle worker long-polling a coordinator
// that vanished without closing its sockets notices within ~15 s); the coordinator permits
// pings at that rate. Reconnect backoff is capped at 2 s (gRPC's default cap is 120 s), so a
// restarted coordinator is found quickly; the worker adds its own jittered backoff on top.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>

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

struct ChannelOptions {
  std::string token;        // bearer token; "" = none
  int keepalive_ms = 10000;  // 0 = no keepalive pings
  int keepalive_timeout_ms = 5000;
  int max_reconnect_backoff_ms = 2000;
};

// An insecure channel to HOST:PORT with the options above (loopback by default; TLS is the
// coordinator's deployment concern, see docs/farm.md).
std::shared_ptr<grpc::Channel> MakeCoordinatorChannel(const std::string& address, const ChannelOptions& options);

// The bearer token: the first line of `token_file` if given (throws InputError if it cannot be
// read or is empty), else $PF_TOKEN, else "".
std::string ResolveToken(const std::string& token_file);

// Sets a deadline `timeout` from now and, if `token` is non-empty, the
// "authorization: Bearer <token>" metadata.
void PrepareContext(grpc::ClientContext* context, const std::string& token, std::chrono::milliseconds timeout);

inline std::chrono::milliseconds Seconds(double s) { return std::chrono::milliseconds(int64_t(s * 1000.0)); }

// "CODE: message" for logs and CLI errors, e.g. "INVALID_ARGUMENT: spec.camera.width/height: must be > 0".
std::string StatusToString(const grpc::Status& status);
const char* StatusCodeName(grpc::StatusCode code);

}  // namespace pf
