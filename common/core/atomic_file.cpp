#include "common/core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <system_error>

#include "common/core/error.h"

namespace pf {
namespace fs = std::filesystem;

namespace {

std::atomic<uint64_t> temporary_counter{0};

[[noreturn]] void Fail(const fs::path& target, const char* step, const fs::path& tmp, int err) {
  throw StorageError(target.string() + ": cannot write (" + step + " " + tmp.string() +
                         "): " + std::system_category().message(err),
                     err);
}

}  // namespace

fs::path TemporarySibling(const fs::path& path) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  // Appended piece by piece: GCC 12 warns (-Wrestrict, a false positive) on "." + string.
  std::string name = ".";
  name += path.filename().string();
  name += ".tmp-";
  name += std::to_string(::getpid());
  name += "-";
  name += std::to_string(temporary_counter.fetch_add(1));
  return dir / name;
}

bool IsTemporaryName(std::string_view filename) {
  return filename.size() > 1 && filename.front() == '.' && filename.find(".tmp-") != std::string_view::npos;
}

int SyncParentDirectory(const fs::path& path, FileLayer& files) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const int dfd = files.Open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC, 0);
  if (dfd < 0) return errno;
  int err = files.Fsync(dfd) == 0 ? 0 : errno;
  if (err == EINVAL || err == EROFS) err = 0;  // the file system does not sync directories
  files.Close(dfd);
  return err;
}

void WriteFileAtomically(const fs::path& path, std::string_view bytes, Durability durability,
                         FileLayer& files) {
  const fs::path tmp = TemporarySibling(path);
  const auto fail = [&](const char* step, int err) {
    files.Unlink(tmp.c_str());
    Fail(path, step, tmp, err);
  };
  const int fd = files.Open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) Fail(path, "open", tmp, errno);
  if (!WriteAllAt(files, fd, bytes.data(), bytes.size(), 0)) {
    const int err = errno;
    files.Close(fd);
    fail("write", err);
  }
  const bool durable = durability == Durability::kDurable;
  if (durable && files.Fsync(fd) != 0) {
    const int err = errno;
    files.Close(fd);
    fail("fsync", err);
  }
  if (files.Close(fd) != 0) fail("close", errno);
  if (files.Rename(tmp.c_str(), path.c_str()) != 0) fail("rename", errno);
  // After the rename the new content is in place; a directory that cannot be synced means it may
  // not survive a power cut, which a durable write must report.
  if (durable)
    if (const int err = SyncParentDirectory(path, files); err != 0)
      throw StorageError(path.string() + ": written, but its directory cannot be synced: " +
                             std::system_category().message(err),
                         err);
}

bool PublishDirectory(const fs::path& tmp, const fs::path& target) {
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (!ec) {
    if (const int err = SyncParentDirectory(target); err != 0)
      throw StorageError(target.string() + ": published, but its directory cannot be synced: " +
                             std::system_category().message(err),
                         err);
    return true;
  }
  fs::remove_all(tmp, ec);
  if (fs::is_directory(target)) return false;  // published by someone else first
  throw SystemError(target.string() + ": cannot publish the directory");
}

}  // namespace pf
