#pragma once
// The system calls of the write paths that must tell the truth about a full disk or a failing
// device (docs/farm.md, "Durability"): the coordinator's result journal and checkpoints, and every
// file written through WriteFileAtomically. They go through one interface so that a test can make
// any single call fail with the errno a real device gives (ENOSPC, EIO, EDQUOT) and check what
// follows — the fault-injection suite (tests/server/storage_faults_test.cpp) does exactly that
// over every write site. Production code uses SystemFiles(), which is the plain POSIX calls.
//
// Every method has the contract of the system call it names: a negative (or -1) result with errno
// set on failure. The methods are virtual but not pure: a fault layer overrides the calls it
// breaks and forwards the rest.

#include <sys/types.h>

#include <cstddef>

namespace pf {

class FileLayer {
 public:
  virtual ~FileLayer() = default;
  virtual int Open(const char* path, int flags, mode_t mode);
  virtual ssize_t Write(int fd, const void* data, size_t size);
  virtual ssize_t PositionedWrite(int fd, const void* data, size_t size, off_t offset);
  virtual int Fsync(int fd);
  virtual int Fdatasync(int fd);
  virtual int Ftruncate(int fd, off_t size);
  virtual int Close(int fd);
  virtual int Rename(const char* from, const char* to);
  virtual int Unlink(const char* path);
};

// The real calls; one instance for the process.
FileLayer& SystemFiles();

// Writes all of `data` at `offset` (retrying short writes and EINTR). False with errno set if the
// layer fails (a short write that makes no progress is reported as ENOSPC, what Linux means by it).
bool WriteAllAt(FileLayer& files, int fd, const void* data, size_t size, off_t offset);

}  // namespace pf
