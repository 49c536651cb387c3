#include "server/store/journal.h"

#include <cstring>
#include <fstream>
#include <sstream>

#include "common/core/error.h"
#include "server/store/checksum.h"

namespace pf::server {
namespace {

constexpr char kMagic[4] = {'P', 'F', 'J', '1'};
constexpr size_t kHeader = 4 + 8 + 4;

void PutLe(std::string& out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(char((v >> (8 * i)) & 0xff));
}
uint64_t GetLe(const char* p, int bytes) {
  uint64_t v = 0;
  for (int i = 0; i < bytes; ++i) v |= uint64_t(static_cast<unsigned char>(p[i])) << (8 * i);
  return v;
}

}  // namespace

std::string EncodeJournalEntry(uint64_t task_id, std::span<const float> rgb_sums) {
  std::string out;
  out.reserve(kHeader + 4 * rgb_sums.size() + 8);
  out.append(kMagic, 4);
  PutLe(out, task_id, 8);
  PutLe(out, rgb_sums.size(), 4);
  for (float f : rgb_sums) {
    uint32_t bits;
    std::memcpy(&bits, &f, 4);
    PutLe(out, bits, 4);
  }
  PutLe(out, Checksum64(out), 8);
  return out;
}

std::vector<JournalEntry> ReadJournalFile(const std::filesystem::path& file, uint64_t* valid_bytes, bool* damaged) {
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
    const uint64_t n = GetLe(p + 12, 4);
    const size_t size = kHeader + 4 * n + 8;
    if (bytes.size() - pos < size) {
      if (damaged) *damaged = another_entry_follows();
      break;
    }
    if (GetLe(p + size - 8, 8) != Checksum64(std::string_view(p, size - 8))) {
      if (damaged) *damaged = bytes.size() - pos > size || another_entry_follows();
      break;
    }
    JournalEntry e;
    e.task_id = GetLe(p + 4, 8);
    e.rgb_sums.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const uint32_t bits = uint32_t(GetLe(p + kHeader + 4 * i, 4));
      std::memcpy(&e.rgb_sums[i], &bits, 4);
    }
    entries.push_back(std::move(e));
    pos += size;
  }
  *valid_bytes = pos;
  return entries;
}

}  // namespace pf::server
