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
  throw SystemError(target.string() + ": cannot write (" + step + " " + tmp.string() +
                    "): " + std::system_category().message(err));
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

void SyncParentDirectory(const fs::path& path) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd < 0) return;
  ::fsync(dfd);
  ::close(dfd);
}

void WriteFileAtomically(const fs::path& path, std::string_view bytes, Durability durability) {
  const fs::path tmp = TemporarySibling(path);
  const auto fail = [&](const char* step, int err) {
    ::unlink(tmp.c_str());
    Fail(path, step, tmp, err);
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) Fail(path, "open", tmp, errno);
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = n < 0 ? errno : EIO;
      ::close(fd);
      fail("write", err);
    }
    done += size_t(n);
  }
  const bool durable = durability == Durability::kDurable;
  if (durable && ::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    fail("fsync", err);
  }
  if (::close(fd) != 0) fail("close", errno);
  if (::rename(tmp.c_str(), path.c_str()) != 0) fail("rename", errno);
  if (durable) SyncParentDirectory(path);
}

bool PublishDirectory(const fs::path& tmp, const fs::path& target) {
  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (!ec) {
    SyncParentDirectory(target);
    return true;
  }
  fs::remove_all(tmp, ec);
  if (fs::is_directory(target)) return false;  // published by someone else first
  throw SystemError(target.string() + ": cannot publish the directory");
}

}  // namespace pf
