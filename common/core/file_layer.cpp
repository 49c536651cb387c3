#include "common/core/file_layer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>

namespace pf {

int FileLayer::Open(const char* path, int flags, mode_t mode) {
  return ::open(path, flags, mode);
}
ssize_t FileLayer::Write(int fd, const void* data, size_t size) {
  return ::write(fd, data, size);
}
ssize_t FileLayer::PositionedWrite(int fd, const void* data, size_t size, off_t offset) {
  return ::pwrite(fd, data, size, offset);
}
int FileLayer::Fsync(int fd) {
  return ::fsync(fd);
}
int FileLayer::Fdatasync(int fd) {
  return ::fdatasync(fd);
}
int FileLayer::Ftruncate(int fd, off_t size) {
  return ::ftruncate(fd, size);
}
int FileLayer::Close(int fd) {
  return ::close(fd);
}
int FileLayer::Rename(const char* from, const char* to) {
  return std::rename(from, to);
}
int FileLayer::Unlink(const char* path) {
  return ::unlink(path);
}

FileLayer& SystemFiles() {
  static FileLayer files;
  return files;
}

bool WriteAllAt(FileLayer& files, int fd, const void* data, size_t size, off_t offset) {
  const char* p = static_cast<const char*>(data);
  size_t done = 0;
  while (done < size) {
    const ssize_t n = files.PositionedWrite(fd, p + done, size - done, offset + off_t(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return false;
    if (n == 0) {
      errno = ENOSPC;
      return false;
    }
    done += size_t(n);
  }
  return true;
}

}  // namespace pf
