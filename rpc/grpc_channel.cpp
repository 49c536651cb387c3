#include "rpc/grpc_channel.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "common/core/error.h"

namespace pf {

RpcError::RpcError(grpc::Status status)
    : std::runtime_error(StatusToString(status)), status_(std::move(status)) {}

std::shared_ptr<grpc::Channel> MakeCoordinatorChannel(const std::string& address, const ChannelOptions& o) {
  grpc::ChannelArguments args;
  if (o.keepalive_ms > 0) {
    args.SetInt(GRPC_ARG_KEEPALIVE_TIME_MS, o.keepalive_ms);
    args.SetInt(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, o.keepalive_timeout_ms);
    args.SetInt(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
    args.SetInt(GRPC_ARG_HTTP2_MAX_PINGS_WITHOUT_DATA, 0);
  }
  args.SetInt(GRPC_ARG_INITIAL_RECONNECT_BACKOFF_MS, 100);
  // gRPC takes this "minimum backoff" as the shortest time a connection attempt may take
  // (TCP connect plus TLS handshake). It must stay long: with the synchronous API an attempt
  // made in the background advances only while a call waits on the channel or when gRPC's
  // backup poller runs (every 5 s), so a short limit aborted every TLS handshake whose reply
  // already sat in the socket, and a worker cut off by a network partition never reconnected
  // ("Handshake read failed", tests/deploy/multihost_test.py). 20 s is gRPC's own default.
  args.SetInt(GRPC_ARG_MIN_RECONNECT_BACKOFF_MS, 20000);
  args.SetInt(GRPC_ARG_MAX_RECONNECT_BACKOFF_MS, o.max_reconnect_backoff_ms);
  // Results of large tiles and scene bundles may exceed the 4 MiB default; the coordinator
  // enforces its own documented limits.
  args.SetMaxReceiveMessageSize(-1);
  args.SetMaxSendMessageSize(-1);
  // Each channel gets its own connection (the tests run several "machines" in one process).
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  if (o.tls.ca_pem.empty())
    return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
  grpc::SslCredentialsOptions ssl;
  ssl.pem_root_certs = o.tls.ca_pem;
  ssl.pem_cert_chain = o.tls.cert_pem;
  ssl.pem_private_key = o.tls.key_pem;
  if (!o.tls.server_name.empty()) args.SetSslTargetNameOverride(o.tls.server_name);
  return grpc::CreateCustomChannel(address, grpc::SslCredentials(ssl), args);
}

namespace {

constexpr size_t kMaxTokenBytes = 4096;

std::string ReadFileOrThrow(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(what + ": cannot read '" + path + "'");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(what + ": cannot read '" + path + "'");
  return std::move(ss).str();
}

std::string EnvOr(std::string value, const char* env) {
  if (!value.empty()) return value;
  const char* v = std::getenv(env);
  return v ? std::string(v) : std::string();
}

}  // namespace

std::string ParseToken(std::string_view text, const std::string& source) {
  const auto is_space = [](char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  };
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  if (text.empty()) throw InputError(source + ": the token is empty");
  if (text.size() > kMaxTokenBytes)
    throw InputError(source + ": the token is longer than " + std::to_string(kMaxTokenBytes) + " bytes");
  for (const char ch : text) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '\n' || ch == '\r')
      throw InputError(source + ": the token must be a single line (it spans several)");
    if (u <= 0x20 || u >= 0x7f)
      throw InputError(source + ": the token may hold only printable ASCII characters without spaces");
  }
  return std::string(text);
}

std::string ResolveToken(const std::string& token_file, const char* env_name, const char* file_env_name) {
  if (!token_file.empty())
    return ParseToken(ReadFileOrThrow(token_file, "--token-file"), "--token-file '" + token_file + "'");
  if (const char* file = file_env_name ? std::getenv(file_env_name) : nullptr) {
    const std::string source = std::string("$") + file_env_name;
    return ParseToken(ReadFileOrThrow(file, source), source + " '" + file + "'");
  }
  const char* env = std::getenv(env_name);
  if (env == nullptr) return "";
  return ParseToken(env, std::string("$") + env_name);
}

ClientTls ResolveClientTls(std::string ca_file, std::string cert_file, std::string key_file) {
  ca_file = EnvOr(std::move(ca_file), "PF_TLS_CA");
  cert_file = EnvOr(std::move(cert_file), "PF_TLS_CERT");
  key_file = EnvOr(std::move(key_file), "PF_TLS_KEY");
  if (cert_file.empty() != key_file.empty()) throw InputError("--tls-cert and --tls-key go together");
  if (!cert_file.empty() && ca_file.empty())
    throw InputError("--tls-cert needs --tls-ca (the roots that sign the coordinator's certificate)");
  ClientTls tls;
  if (!ca_file.empty()) tls.ca_pem = ReadFileOrThrow(ca_file, "--tls-ca");
  if (!cert_file.empty()) {
    tls.cert_pem = ReadFileOrThrow(cert_file, "--tls-cert");
    tls.key_pem = ReadFileOrThrow(key_file, "--tls-key");
  }
  return tls;
}

void PrepareContext(grpc::ClientContext* context, const std::string& token,
                    std::chrono::milliseconds timeout) {
  context->set_deadline(std::chrono::system_clock::now() + timeout);
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
}

const char* StatusCodeName(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return "OK";
    case grpc::StatusCode::CANCELLED:
      return "CANCELLED";
    case grpc::StatusCode::UNKNOWN:
      return "UNKNOWN";
    case grpc::StatusCode::INVALID_ARGUMENT:
      return "INVALID_ARGUMENT";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "DEADLINE_EXCEEDED";
    case grpc::StatusCode::NOT_FOUND:
      return "NOT_FOUND";
    case grpc::StatusCode::ALREADY_EXISTS:
      return "ALREADY_EXISTS";
    case grpc::StatusCode::PERMISSION_DENIED:
      return "PERMISSION_DENIED";
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::FAILED_PRECONDITION:
      return "FAILED_PRECONDITION";
    case grpc::StatusCode::ABORTED:
      return "ABORTED";
    case grpc::StatusCode::OUT_OF_RANGE:
      return "OUT_OF_RANGE";
    case grpc::StatusCode::UNIMPLEMENTED:
      return "UNIMPLEMENTED";
    case grpc::StatusCode::INTERNAL:
      return "INTERNAL";
    case grpc::StatusCode::UNAVAILABLE:
      return "UNAVAILABLE";
    case grpc::StatusCode::DATA_LOSS:
      return "DATA_LOSS";
    case grpc::StatusCode::UNAUTHENTICATED:
      return "UNAUTHENTICATED";
    default:
      return "STATUS";
  }
}

std::string StatusToString(const grpc::Status& status) {
  return std::string(StatusCodeName(status.error_code())) + ": " + status.error_message();
}

}  // namespace pf
