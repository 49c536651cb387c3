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
  // cut failed, it is done here, before anything is appended behind a torn entry.
  uint64_t valid = 0;
  try {
    ReadJournalFile(file_, &valid);
  } catch (const std::exception& e) {
    *problem = std::string("cannot read the journal: ") + e.what();
    Break();
    return false;
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
  return true;
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
