#pragma once
// Why a TLS connection to the coordinator failed (docs/security.md, "Certificate diagnostics").
// gRPC reports a refused client certificate as UNAVAILABLE "failed to connect to all addresses;
// ... Socket closed", in the same words as a coordinator that is down or that speaks plaintext:
// with TLS 1.3 the server judges the client's certificate after the client has finished its
// side of the handshake, sends an alert and closes, and gRPC keeps only "closed". So after an
// UNAVAILABLE on a TLS channel, one handshake of our own with OpenSSL — the same roots, client
// certificate, server name and ALPN "h2" as the channel — reads the coordinator's first answer:
// its alert names what it refused; our own verification names what we refused.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <string>

#include "rpc/grpc_channel.h"

namespace pf {

// "" when there is nothing TLS-specific to say: no TCP connection to `address` at all (then
// "unreachable" is the truth), a unix: target, or a handshake that succeeds and is answered. Else
// one sentence, "TLS handshake with ADDRESS failed: ...", e.g. "the coordinator refused this
// client's certificate: it expired on 2024-05-01 12:00:00 UTC (renew --tls-cert)". Takes at most
// `timeout`.
std::string DiagnoseTlsHandshake(const std::string& address, const ClientTls& tls,
                                 std::chrono::milliseconds timeout = std::chrono::milliseconds(3000));

// `status` itself, unless it is UNAVAILABLE, `tls` is in use and DiagnoseTlsHandshake names a
// cause: then UNAVAILABLE with that sentence as the message (the code, and so every exit code
// derived from it, stays the same).
grpc::Status ExplainTlsFailure(const grpc::Status& status, const std::string& address, const ClientTls& tls);

}  // namespace pf
