#include "server/rpc/status_mapping.h"

#include <spdlog/spdlog.h>

#include <new>

#include "common/core/error.h"
#include "proto/convert.h"
#include "server/errors.h"

namespace pf::server {

grpc::Status StatusFromException(std::exception_ptr error, std::string_view rpc) {
  try {
    std::rethrow_exception(error);
  } catch (const LimitError& e) {
    spdlog::info("{}: RESOURCE_EXHAUSTED: {}", rpc, e.what());
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, e.what()};
  } catch (const InputError& e) {
    spdlog::info("{}: INVALID_ARGUMENT: {}", rpc, e.what());
    return {grpc::StatusCode::INVALID_ARGUMENT, e.what()};
  } catch (const NotFoundError& e) {
    spdlog::info("{}: NOT_FOUND: {}", rpc, e.what());
    return {grpc::StatusCode::NOT_FOUND, e.what()};
  } catch (const DataLossError& e) {
    spdlog::error("{}: DATA_LOSS: {}", rpc, e.what());
    return {grpc::StatusCode::DATA_LOSS, e.what()};
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
