#include "server/store/checkpoint.h"

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "common/core/atomic_file.h"
#include "common/core/byte_codec.h"
#include "common/core/error.h"
#include "server/store/checksum.h"

namespace pf::server {
namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'P', 'F', 'C', 'K', 'P', 'T', '0', '1'};
// 3: with the convicted workers; 2: with the job's epoch; 1 (before epochs) reads as epoch 0.
constexpr uint32_t kVersion = 3;

}  // namespace

std::string EncodeCheckpoint(const Checkpoint& cp) {
  std::string out;
  out.reserve(64 + cp.job_id.size() + 8 * cp.merged_task_ids.size() + cp.accumulator.size());
  ByteWriter w(out);
  w.PutBytes(std::string_view(kMagic, sizeof(kMagic)));
  w.Put<uint32_t>(kVersion);
  w.Put<uint32_t>(uint32_t(cp.job_id.size()));
  w.PutBytes(cp.job_id);
  w.Put<uint64_t>(cp.merge_seq);
  w.Put<uint32_t>(cp.epoch);
  std::string convicted;
  for (const std::string& worker : cp.convicted) convicted += worker + "\n";
  w.Put<uint32_t>(uint32_t(convicted.size()));
  w.PutBytes(convicted);
  w.Put<uint64_t>(cp.merged_task_ids.size());
  w.PutArray<uint64_t>(cp.merged_task_ids);
  w.Put<uint64_t>(cp.accumulator.size());
  w.PutBytes(cp.accumulator);
  w.Put<uint64_t>(Checksum64(out));
  return out;
}

Checkpoint DecodeCheckpoint(std::string_view bytes, CheckpointSeal* seal) {
  if (bytes.size() < sizeof(kMagic) + 8 || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError("checkpoint: bad magic");
  const uint64_t stored = LoadLittleEndian<uint64_t>(bytes.data() + bytes.size() - 8);
  if (stored != Checksum64(bytes.substr(0, bytes.size() - 8)))
    throw InputError("checkpoint: checksum mismatch");
  if (seal) seal->digest = stored;
  ByteReader in(bytes.substr(sizeof(kMagic), bytes.size() - sizeof(kMagic) - 8), "checkpoint");
  const uint32_t version = in.Get<uint32_t>();
  if (version < 1 || version > kVersion)
    throw InputError("checkpoint: unsupported version " + std::to_string(version));
  Checkpoint cp;
  const uint32_t id_len = in.Get<uint32_t>();
  cp.job_id = std::string(in.GetBytes(id_len));
  cp.merge_seq = in.Get<uint64_t>();
  cp.epoch = version >= 2 ? in.Get<uint32_t>() : 0;
  if (version >= 3) {
    const std::string_view convicted = in.GetBytes(in.Get<uint32_t>());
    for (size_t at = 0; at < convicted.size();) {
      const size_t end = convicted.find('\n', at);
      if (end == std::string_view::npos) throw InputError("checkpoint: convicted workers not terminated");
      if (end == at) throw InputError("checkpoint: an empty convicted worker id");
      cp.convicted.emplace_back(convicted.substr(at, end - at));
      at = end + 1;
    }
  }
  const uint64_t n = in.Get<uint64_t>();
  if (n > in.remaining() / 8) throw InputError("checkpoint: truncated");
  cp.merged_task_ids.reserve(size_t(n));
  for (uint64_t i = 0; i < n; ++i) {
    cp.merged_task_ids.push_back(in.Get<uint64_t>());
    if (i > 0 && cp.merged_task_ids[i] <= cp.merged_task_ids[i - 1])
      throw InputError("checkpoint: merged task ids not ascending");
  }
  const uint64_t acc_len = in.Get<uint64_t>();
  cp.accumulator = std::string(in.GetBytes(acc_len));
  if (!in.empty()) in.Fail("trailing bytes");
  if (seal) seal->tasks = cp.merged_task_ids.size();
  return cp;
}

namespace {

std::optional<std::string> ReadBytes(const fs::path& file) {
  std::error_code ec;
  const fs::file_status status = fs::status(file, ec);
  if (status.type() == fs::file_type::not_found) return std::nullopt;
  if (ec) throw SystemError(file.string() + ": cannot look at the checkpoint: " + ec.message());
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SystemError(file.string() + ": cannot open checkpoint");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (!in && !in.eof()) throw SystemError(file.string() + ": cannot read checkpoint");
  return std::move(ss).str();
}

}  // namespace

CheckpointSeal WriteCheckpointFile(const fs::path& file, const Checkpoint& cp, FileLayer& files) {
  const std::string bytes = EncodeCheckpoint(cp);
  WriteFileAtomically(file, bytes, Durability::kDurable, files);
  // Read back before anything relies on it (the journal it replaces is truncated after this).
  std::optional<std::string> back;
  try {
    back = ReadBytes(file);
  } catch (const std::exception& e) {
    throw StorageError(file.string() + ": written but not readable back: " + e.what(), EIO);
  }
  if (!back || *back != bytes)
    throw StorageError(file.string() + ": read back differs from what was written", EIO);
  CheckpointSeal seal;
  DecodeCheckpoint(bytes, &seal);
  return seal;
}

std::optional<Checkpoint> ReadCheckpointFile(const fs::path& file, CheckpointSeal* seal) {
  const std::optional<std::string> bytes = ReadBytes(file);
  if (!bytes) return std::nullopt;
  try {
    return DecodeCheckpoint(*bytes, seal);
  } catch (const InputError& e) {
    throw InputError(file.string() + ": " + e.what());
  }
}

std::string VerifyCheckpointFile(const fs::path& file, const CheckpointSeal& expected,
                                 std::optional<Checkpoint>* checkpoint, bool* unreadable) {
  std::optional<Checkpoint> cp;
  CheckpointSeal seal;
  if (unreadable) *unreadable = false;
  try {
    std::optional<std::string> bytes = ReadBytes(file);
    if (bytes) cp = DecodeCheckpoint(*bytes, &seal);
  } catch (const SystemError& e) {
    // The file system failed (EIO, EACCES, EMFILE…): the file may be fine. Not a lost image.
    if (unreadable) *unreadable = true;
    return std::string("cannot be read (") + e.what() + ")";
  } catch (const std::exception& e) {
    std::string reason = e.what();
    if (const size_t at = reason.rfind("checkpoint:"); at != std::string::npos) reason = reason.substr(at);
    return "is damaged (" + reason + ")";
  }
  if (!cp) return expected.tasks == 0 ? "" : "is missing";
  if (seal.tasks != expected.tasks)
    return "holds " + std::to_string(seal.tasks) + " tasks, " + std::to_string(expected.tasks) + " expected";
  if (expected.digest != 0 && seal.digest != expected.digest)
    return "is another checkpoint (digest " + DigestText(seal.digest) + ", " + DigestText(expected.digest) +
           " expected)";
  if (checkpoint) *checkpoint = std::move(cp);
  return "";
}

}  // namespace pf::server
