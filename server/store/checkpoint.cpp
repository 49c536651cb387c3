#include "server/store/checkpoint.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "common/core/error.h"
#include "server/store/checksum.h"

namespace pf::server {
namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'P', 'F', 'C', 'K', 'P', 'T', '0', '1'};
constexpr uint32_t kVersion = 1;

template <typename T>
void Put(std::string& out, T v) {
  char buf[sizeof(T)];
  for (size_t i = 0; i < sizeof(T); ++i) buf[i] = char((uint64_t(v) >> (8 * i)) & 0xff);
  out.append(buf, sizeof(T));
}

template <typename T>
T Get(std::string_view& in) {
  if (in.size() < sizeof(T)) throw InputError("checkpoint: truncated");
  uint64_t v = 0;
  for (size_t i = 0; i < sizeof(T); ++i) v |= uint64_t(static_cast<unsigned char>(in[i])) << (8 * i);
  in.remove_prefix(sizeof(T));
  return T(v);
}

std::string_view GetBytes(std::string_view& in, uint64_t n) {
  if (in.size() < n) throw InputError("checkpoint: truncated");
  std::string_view out = in.substr(0, size_t(n));
  in.remove_prefix(size_t(n));
  return out;
}

[[noreturn]] void ThrowErrno(const std::string& what, const fs::path& path) {
  throw SystemError(path.string() + ": " + what + ": " + std::strerror(errno));
}

}  // namespace

std::string EncodeCheckpoint(const Checkpoint& cp) {
  std::string out;
  out.reserve(64 + cp.job_id.size() + 8 * cp.merged_task_ids.size() + cp.accumulator.size());
  out.append(kMagic, sizeof(kMagic));
  Put<uint32_t>(out, kVersion);
  Put<uint32_t>(out, uint32_t(cp.job_id.size()));
  out += cp.job_id;
  Put<uint64_t>(out, cp.merge_seq);
  Put<uint64_t>(out, cp.merged_task_ids.size());
  for (uint64_t id : cp.merged_task_ids) Put<uint64_t>(out, id);
  Put<uint64_t>(out, cp.accumulator.size());
  out += cp.accumulator;
  Put<uint64_t>(out, Checksum64(out));
  return out;
}

Checkpoint DecodeCheckpoint(std::string_view bytes) {
  if (bytes.size() < sizeof(kMagic) + 8 || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError("checkpoint: bad magic");
  std::string_view tail = bytes.substr(bytes.size() - 8);
  const uint64_t stored = Get<uint64_t>(tail);
  if (stored != Checksum64(bytes.substr(0, bytes.size() - 8))) throw InputError("checkpoint: checksum mismatch");
  std::string_view in = bytes.substr(sizeof(kMagic), bytes.size() - sizeof(kMagic) - 8);
  const uint32_t version = Get<uint32_t>(in);
  if (version != kVersion) throw InputError("checkpoint: unsupported version " + std::to_string(version));
  Checkpoint cp;
  const uint32_t id_len = Get<uint32_t>(in);
  cp.job_id = std::string(GetBytes(in, id_len));
  cp.merge_seq = Get<uint64_t>(in);
  const uint64_t n = Get<uint64_t>(in);
  if (n > in.size() / 8) throw InputError("checkpoint: truncated");
  cp.merged_task_ids.reserve(size_t(n));
  for (uint64_t i = 0; i < n; ++i) {
    cp.merged_task_ids.push_back(Get<uint64_t>(in));
    if (i > 0 && cp.merged_task_ids[i] <= cp.merged_task_ids[i - 1])
      throw InputError("checkpoint: merged task ids not ascending");
  }
  const uint64_t acc_len = Get<uint64_t>(in);
  cp.accumulator = std::string(GetBytes(in, acc_len));
  if (!in.empty()) throw InputError("checkpoint: trailing bytes");
  return cp;
}

void WriteFileAtomically(const fs::path& file, std::string_view bytes) {
  const fs::path tmp = file.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) ThrowErrno("cannot create", tmp);
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int saved = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      errno = saved;
      ThrowErrno("write failed", tmp);
    }
    done += size_t(n);
  }
  if (::fsync(fd) != 0) {
    const int saved = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    errno = saved;
    ThrowErrno("fsync failed", tmp);
  }
  ::close(fd);
  if (::rename(tmp.c_str(), file.c_str()) != 0) {
    const int saved = errno;
    ::unlink(tmp.c_str());
    errno = saved;
    ThrowErrno("rename failed", file);
  }
  const fs::path dir = file.has_parent_path() ? file.parent_path() : fs::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
}

void WriteCheckpointFile(const fs::path& file, const Checkpoint& cp) { WriteFileAtomically(file, EncodeCheckpoint(cp)); }

std::optional<Checkpoint> ReadCheckpointFile(const fs::path& file) {
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SystemError(file.string() + ": cannot open checkpoint");
  std::ostringstream ss;
  ss << in.rdbuf();
  try {
    return DecodeCheckpoint(ss.str());
  } catch (const InputError& e) {
    throw InputError(file.string() + ": " + e.what());
  }
}

}  // namespace pf::server
