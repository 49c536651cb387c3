#pragma once
// Errors the coordinator's logic throws besides the core's (common/core/error.h: InputError →
// INVALID_ARGUMENT; proto/convert.h: LimitError → RESOURCE_EXHAUSTED). The single mapping to
// gRPC status codes is server/rpc/status_mapping.h.

#include <stdexcept>
#include <string>

namespace pf::server {

// A job, scene or lease that does not exist. The message names the field ("job_id: unknown job
// 'job-7'"). → NOT_FOUND.
class NotFoundError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The coordinator cannot take the request now (shutting down, work queue full). → UNAVAILABLE.
class UnavailableError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The request is valid but the job's state forbids it (pausing a finished job). The message names
// the state ("job 'job-…' is SUCCEEDED: …"). → FAILED_PRECONDITION.
class PreconditionError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Data the coordinator had acknowledged is gone or corrupt (a damaged checkpoint of a finished
// job). The message names the job, never a server path. → DATA_LOSS (clients must not read it
// as "your input was invalid").
class DataLossError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pf::server
