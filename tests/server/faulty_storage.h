#pragma once
// Storage that fails on purpose, for the fault-injection suite (storage_faults_test.cpp):
//   FaultyFiles   a FileLayer (common/core/file_layer.h) whose calls fail by rule — the result
//                 journal, checkpoints and every WriteFileAtomically of the coordinator;
//   FaultySqlite  a SQLite VFS, registered as the default while it lives, whose writes and syncs
//                 of the database files fail by the same rules.
// A rule names a call and a part of its file's path, which matching call fails first, how many
// fail from there, and the errno a real device gives (ENOSPC: full, EIO: failing). A failing write
// can first write half of its bytes, as a device that fills up in the middle of a write does.

#include <sys/types.h>

#include <cerrno>
#include <cstdint>
#include <limits>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/file_layer.h"

namespace pf::server::testing {

enum class FileOp {
  kOpen,
  kWrite,
  kFsync,
  kFdatasync,
  kFtruncate,
  kClose,
  kRename,
  kUnlink,
  kSqliteWrite,
  kSqliteSync
};

struct FaultRule {
  FileOp op = FileOp::kWrite;
  std::string path_part;    // the call's file (for a rename: its target) contains this…
  bool at_end = false;      // … at its end
  uint64_t first_call = 1;  // the first matching call that fails (1-based)
  uint64_t count = 1;       // how many matching calls fail from there on
  int error = ENOSPC;
  bool torn = false;  // a failing write first writes half of its bytes
  static constexpr uint64_t kUntilDisarmed = std::numeric_limits<uint64_t>::max();
};

// The rules in force and the calls they matched; thread-safe.
class FaultInjector {
 public:
  void Arm(const FaultRule& rule);  // in force beside the others
  void Disarm();                    // all of them
  bool armed() const;
  uint64_t failures() const;  // calls failed since construction
  // Counts the call against every rule it matches; true (with the first failing rule's errno
  // and tear) if one of them fails it.
  bool ShouldFail(FileOp op, std::string_view path, int* error, bool* torn);

 private:
  struct Armed {
    FaultRule rule;
    uint64_t matched = 0;
  };
  mutable std::mutex mu_;
  std::vector<Armed> rules_;
  uint64_t failures_ = 0;
};

class FaultyFiles final : public FileLayer {
 public:
  explicit FaultyFiles(FaultInjector& faults) : faults_(faults) {}
  int Open(const char* path, int flags, mode_t mode) override;
  ssize_t Write(int fd, const void* data, size_t size) override;
  ssize_t PositionedWrite(int fd, const void* data, size_t size, off_t offset) override;
  int Fsync(int fd) override;
  int Fdatasync(int fd) override;
  int Ftruncate(int fd, off_t size) override;
  int Close(int fd) override;
  int Rename(const char* from, const char* to) override;
  int Unlink(const char* path) override;

 private:
  std::string PathOf(int fd);
  bool Fails(FileOp op, std::string_view path, bool* torn = nullptr);
  FaultInjector& faults_;
  std::mutex mu_;
  std::map<int, std::string> paths_;
};

// Registers a VFS that wraps SQLite's default one as the new default; restores the old default
// when destroyed. One at a time.
class FaultySqlite {
 public:
  explicit FaultySqlite(FaultInjector& faults);
  ~FaultySqlite();
  FaultySqlite(const FaultySqlite&) = delete;
  FaultySqlite& operator=(const FaultySqlite&) = delete;
};

}  // namespace pf::server::testing
