#pragma once
// The one mapping from the core's and the coordinator's errors to gRPC status codes (docs/design.md, §3;
// "errors as values inside, mapped to gRPC status codes in one function at the edge"):
//
//   pf::LimitError (proto/convert.h)        RESOURCE_EXHAUSTED   over a documented limit
//   pf::InputError                          INVALID_ARGUMENT     message starts with the field
//                                                                path or the scene's file:line
//   pf::server::NotFoundError               NOT_FOUND            unknown job / scene / lease
//   pf::server::UnavailableError            UNAVAILABLE          shutting down, queue full
//   std::bad_alloc                          RESOURCE_EXHAUSTED
//   pf::SystemError, std::exception         INTERNAL             logged with the RPC name
//   anything else                           UNKNOWN              logged
//
// Handlers run their logic through Guarded(), so no exception escapes into gRPC.

#include <exception>
#include <string_view>

#include <grpcpp/support/status.h>

namespace pf::server {

grpc::Status StatusFromException(std::exception_ptr error, std::string_view rpc);

template <typename F>
grpc::Status Guarded(std::string_view rpc, F&& body) {
  try {
    return body();
  } catch (...) {
    return StatusFromException(std::current_exception(), rpc);
  }
}

}  // namespace pf::server
