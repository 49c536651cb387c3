#pragma once
// User-facing errors (docs/design.md, §3: three tiers of errors). Malformed input is reported with the file
// and line it came from and the reason; such errors are thrown inside the core and caught at
// the edges (CLI, coordinator, worker), which turn them into messages and exit codes / statuses.

#include <stdexcept>
#include <string>

namespace pf {

// Where a piece of user input came from. line == 0 means "the whole file".
struct SourceLocation {
  std::string file;
  int line = 0;
  std::string ToString() const { return line > 0 ? file + ":" + std::to_string(line) : file; }
};

// An error in user input (scene file, manifest, command line, job request).
class InputError : public std::runtime_error {
 public:
  InputError(SourceLocation where, const std::string& reason)
      : std::runtime_error(where.ToString() + ": " + reason), where_(std::move(where)), reason_(reason) {}
  explicit InputError(const std::string& reason) : std::runtime_error(reason), reason_(reason) {}
  const SourceLocation& where() const { return where_; }
  const std::string& reason() const { return reason_; }

 private:
  SourceLocation where_;
  std::string reason_;
};

// Input that is well-formed but over a resource limit (docs/security.md, "Limits"): the RPC
// layers answer RESOURCE_EXHAUSTED for it rather than INVALID_ARGUMENT.
class LimitError : public InputError {
 public:
  using InputError::InputError;
};

// Work given up on request (a cancel flag was set): e.g. a worker whose lease is gone stops
// rendering a task whose result would be dropped anyway. Not an error of the input or the machine.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

// A failure of the machine or a library (cannot write a file, Embree device error...).
class SystemError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A file could not be written, synced or renamed: the disk is full or failing (the errno says
// which). Nothing was half-done: the write paths that throw it leave the old state in place
// (common/core/atomic_file.h), so the same call may succeed once space is freed. The coordinator
// answers UNAVAILABLE for it, not INTERNAL (server/rpc/status_mapping.h).
class StorageError : public SystemError {
 public:
  StorageError(const std::string& what, int error_number) : SystemError(what), error_number_(error_number) {}
  int error_number() const { return error_number_; }

 private:
  int error_number_;
};

}  // namespace pf
