#include "server/store/journal.h"

#include <fcntl.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include "common/core/byte_codec.h"
#include "common/core/error.h"
#include "server/store/checksum.h"

namespace pf::server {
namespace {

constexpr char kMagic[4] = {'P', 'F', 'J', '2'};
constexpr char kMagicV1[4] = {'P', 'F', 'J', '1'};  // before epochs: no epoch field
constexpr size_t kHeader = 4 + 8 + 4 + 4;
constexpr size_t kHeaderV1 = 4 + 8 + 4;

}  // namespace

std::string EncodeJournalEntry(uint64_t task_id, uint32_t epoch, std::span<const float> rgb_sums) {
  std::string out;
  out.reserve(kHeader + 4 * rgb_sums.size() + 8);
  ByteWriter w(out);
  w.PutBytes(std::string_view(kMagic, 4));
  w.Put<uint64_t>(task_id);
  w.Put<uint32_t>(epoch);
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
  while (bytes.size() - pos >= kHeaderV1 + 8) {
    const char* p = bytes.data() + pos;
    const auto another_entry_follows = [&] {
      const std::string_view rest = std::string_view(bytes).substr(pos + 1);
      return rest.find(std::string_view(kMagic, 4)) != std::string_view::npos ||
             rest.find(std::string_view(kMagicV1, 4)) != std::string_view::npos;
    };
    const bool v1 = std::memcmp(p, kMagicV1, 4) == 0;
    if (!v1 && std::memcmp(p, kMagic, 4) != 0) {
      if (damaged) *damaged = another_entry_follows();
      break;
    }
    const size_t header = v1 ? kHeaderV1 : kHeader;
    if (bytes.size() - pos < header + 8) {
      if (damaged) *damaged = another_entry_follows();
      break;
    }
    const uint64_t n = LoadLittleEndian<uint32_t>(p + header - 4);
    const size_t size = header + 4 * n + 8;
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
    e.epoch = v1 ? 0 : LoadLittleEndian<uint32_t>(p + 12);
    e.rgb_sums.resize(n);
    ByteReader(std::string_view(p + header, 4 * n), "journal entry").GetArray<float>(e.rgb_sums);
    entries.push_back(std::move(e));
    pos += size;
  }
  *valid_bytes = pos;
  return entries;
}

JournalWriter::JournalWriter(std::filesystem::path file, FileLayer& files)
    : file_(std::move(file)), files_(files) {}

JournalWriter::~JournalWriter() {
  if (fd_ >= 0) files_.Close(fd_);
}

void JournalWriter::Break() {
  broken_ = true;
  if (fd_ >= 0) files_.Close(fd_);
  fd_ = -1;
}

bool JournalWriter::Open(std::string* problem) {
  // A journal left by an earlier run was cut back to its last good entry by recovery; if that
  // cut failed, it is done here, before anything is appended behind a torn entry. A journal this
  // writer had open before ends where the writer says.
  uint64_t valid = end_;
  if (!end_known_) {
    try {
      ReadJournalFile(file_, &valid);
    } catch (const std::exception& e) {
      *problem = std::string("cannot read the journal: ") + e.what();
      Break();
      return false;
    }
  }
  fd_ = files_.Open(file_.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    *problem = "cannot open the journal: " + std::system_category().message(errno);
    Break();
    return false;
  }
  std::error_code ec;
  const uint64_t size = std::filesystem::file_size(file_, ec);
  if (!ec && size > valid && files_.Ftruncate(fd_, off_t(valid)) != 0) {
    *problem = "cannot cut the journal's torn tail: " + std::system_category().message(errno);
    Break();
    return false;
  }
  end_ = valid;
  end_known_ = true;
  return true;
}

void JournalWriter::CloseFile() {
  if (fd_ >= 0) files_.Close(fd_);
  fd_ = -1;
}

bool JournalWriter::Append(std::string_view entry, std::string* problem) {
  if (broken_) {
    *problem = "the journal is out of service until the next checkpoint";
    return false;
  }
  if (fd_ < 0 && !Open(problem)) return false;
  if (WriteAllAt(files_, fd_, entry.data(), entry.size(), off_t(end_))) {
    end_ += entry.size();
    appended_ += entry.size();
    return true;
  }
  *problem = "journal write: " + std::system_category().message(errno);
  if (files_.Ftruncate(fd_, off_t(end_)) != 0) {
    *problem += "; the torn entry cannot be cut off (" + std::system_category().message(errno) + ")";
    Break();
  }
  return false;
}

bool JournalWriter::Sync(std::string* problem) {
  if (broken_ || fd_ < 0) return !broken_;
  if (files_.Fdatasync(fd_) == 0) return true;
  *problem = "journal fdatasync: " + std::system_category().message(errno);
  Break();
  return false;
}

bool JournalWriter::Reset(std::string* problem) {
  if (!broken_) {
    if (fd_ < 0) {
      std::error_code ec;
      if (!std::filesystem::exists(file_, ec)) return true;  // nothing was ever appended
      if (!Open(problem)) return false;
    }
    if (files_.Ftruncate(fd_, 0) == 0 && files_.Fdatasync(fd_) == 0) {
      end_ = 0;
      appended_ = 0;
      return true;
    }
    *problem = "cannot empty the journal: " + std::system_category().message(errno);
    Break();
  }
  if (files_.Unlink(file_.c_str()) != 0 && errno != ENOENT) {
    *problem = "cannot remove the journal: " + std::system_category().message(errno);
    return false;
  }
  broken_ = false;
  end_ = 0;
  end_known_ = true;  // no file: the next Append creates it
  appended_ = 0;
  return true;
}

void JournalWriter::Remove() {
  if (fd_ >= 0) files_.Close(fd_);
  fd_ = -1;
  files_.Unlink(file_.c_str());
  broken_ = false;
  end_ = 0;
  appended_ = 0;
}

}  // namespace pf::server
