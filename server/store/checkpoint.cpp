#include "server/store/checkpoint.h"

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
constexpr uint32_t kVersion = 1;

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
  w.Put<uint64_t>(cp.merged_task_ids.size());
  w.PutArray<uint64_t>(cp.merged_task_ids);
  w.Put<uint64_t>(cp.accumulator.size());
  w.PutBytes(cp.accumulator);
  w.Put<uint64_t>(Checksum64(out));
  return out;
}

Checkpoint DecodeCheckpoint(std::string_view bytes) {
  if (bytes.size() < sizeof(kMagic) + 8 || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError("checkpoint: bad magic");
  const uint64_t stored = LoadLittleEndian<uint64_t>(bytes.data() + bytes.size() - 8);
  if (stored != Checksum64(bytes.substr(0, bytes.size() - 8)))
    throw InputError("checkpoint: checksum mismatch");
  ByteReader in(bytes.substr(sizeof(kMagic), bytes.size() - sizeof(kMagic) - 8), "checkpoint");
  const uint32_t version = in.Get<uint32_t>();
  if (version != kVersion) throw InputError("checkpoint: unsupported version " + std::to_string(version));
  Checkpoint cp;
  const uint32_t id_len = in.Get<uint32_t>();
  cp.job_id = std::string(in.GetBytes(id_len));
  cp.merge_seq = in.Get<uint64_t>();
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
  return cp;
}

void WriteCheckpointFile(const fs::path& file, const Checkpoint& cp) {
  WriteFileAtomically(file, EncodeCheckpoint(cp));
}

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
