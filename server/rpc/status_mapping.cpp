#include "server/rpc/status_mapping.h"

#include <spdlog/spdlog.h>

#include <new>

#include "common/core/error.h"
#include "proto/convert.h"
#include "server/errors.h"

namespace pf::server {
namespace {

// The error's own message as the status, logged at `level` as "rpc: CODE: message".
grpc::Status Logged(spdlog::level::level_enum level, std::string_view rpc, grpc::StatusCode code,
                    std::string_view code_name, const std::exception& e) {
  spdlog::log(level, "{}: {}: {}", rpc, code_name, e.what());
  return {code, e.what()};
}

}  // namespace

grpc::Status StatusFromException(std::exception_ptr error, std::string_view rpc) {
  try {
    std::rethrow_exception(error);
  } catch (const LimitError& e) {
    return Logged(spdlog::level::info, rpc, grpc::StatusCode::RESOURCE_EXHAUSTED, "RESOURCE_EXHAUSTED", e);
  } catch (const InputError& e) {
    return Logged(spdlog::level::info, rpc, grpc::StatusCode::INVALID_ARGUMENT, "INVALID_ARGUMENT", e);
  } catch (const NotFoundError& e) {
    return Logged(spdlog::level::info, rpc, grpc::StatusCode::NOT_FOUND, "NOT_FOUND", e);
  } catch (const PreconditionError& e) {
    return Logged(spdlog::level::info, rpc, grpc::StatusCode::FAILED_PRECONDITION, "FAILED_PRECONDITION", e);
  } catch (const DataLossError& e) {
    return Logged(spdlog::level::err, rpc, grpc::StatusCode::DATA_LOSS, "DATA_LOSS", e);
  } catch (const UnavailableError& e) {
    return {grpc::StatusCode::UNAVAILABLE, e.what()};
  } catch (const StorageError& e) {
    // A full or failing disk: nothing was half-written, the same call may succeed later.
    spdlog::error("{}: UNAVAILABLE: storage: {}", rpc, e.what());
    return {grpc::StatusCode::UNAVAILABLE, std::string("the coordinator cannot store this now: ") + e.what()};
  } catch (const std::bad_alloc&) {
    spdlog::error("{}: out of memory", rpc);
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "out of memory"};
  } catch (const std::exception& e) {
    spdlog::error("{}: internal error: {}", rpc, e.what());
    return {grpc::StatusCode::INTERNAL, std::string("internal error: ") + e.what()};
  } catch (...) {
    spdlog::error("{}: unknown exception", rpc);
    return {grpc::StatusCode::UNKNOWN, "unknown error"};
  }
}

}  // namespace pf::server
