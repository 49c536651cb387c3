#include "server/store/journal.h"

#include <cstring>
#include <fstream>
#include <sstream>

#include "common/core/byte_codec.h"
#include "common/core/error.h"
#include "server/store/checksum.h"

namespace pf::server {
namespace {

constexpr char kMagic[4] = {'P', 'F', 'J', '1'};
constexpr size_t kHeader = 4 + 8 + 4;

}  // namespace

std::string EncodeJournalEntry(uint64_t task_id, std::span<const float> rgb_sums) {
  std::string out;
  out.reserve(kHeader + 4 * rgb_sums.size() + 8);
  ByteWriter w(out);
  w.PutBytes(std::string_view(kMagic, 4));
  w.Put<uint64_t>(task_id);
  w.Put<uint32_t>(uint32_t(rgb_sums.size()));
  w.PutArray<float>(rgb_sums);
  w.Put<uint64_t>(Checksum64(out));
  return out;
}

std::vector<JournalEntry> ReadJournalFile(const std::filesystem::path& file, uint64_t* valid_bytes,
                                          bool* damaged) {
  *valid_bytes = 0;
  if (damaged) *damaged = false;
  std::vector<JournalEntry> entries;
  std::error_code ec;
  if (!std::filesystem::exists(file, ec)) return entries;
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SystemError(file.string() + ": cannot open the journal");
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string bytes = std::move(ss).str();
  size_t pos = 0;
  while (bytes.size() - pos >= kHeader + 8) {
    const char* p = bytes.data() + pos;
    const auto another_entry_follows = [&] {
      return std::string_view(bytes).find(std::string_view(kMagic, 4), pos + 1) != std::string_view::npos;
    };
    if (std::memcmp(p, kMagic, 4) != 0) {
      if (damaged) *damaged = another_entry_follows();
      break;
    }
    const uint64_t n = LoadLittleEndian<uint32_t>(p + 12);
    const size_t size = kHeader + 4 * n + 8;
    if (bytes.size() - pos < size) {
      if (damaged) *damaged = another_entry_follows();
      break;
    }
    if (LoadLittleEndian<uint64_t>(p + size - 8) != Checksum64(std::string_view(p, size - 8))) {
      if (damaged) *damaged = bytes.size() - pos > size || another_entry_follows();
      break;
    }
    JournalEntry e;
    e.task_id = LoadLittleEndian<uint64_t>(p + 4);
    e.rgb_sums.resize(n);
    ByteReader(std::string_view(p + kHeader, 4 * n), "journal entry").GetArray<float>(e.rgb_sums);
    entries.push_back(std::move(e));
    pos += size;
  }
  *valid_bytes = pos;
  return entries;
}

}  // namespace pf::server
