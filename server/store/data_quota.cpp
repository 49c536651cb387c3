#include "server/store/data_quota.h"

namespace pf::server {
namespace fs = std::filesystem;

uint64_t DirectoryBytes(const fs::path& dir) {
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end; it.increment(ec)) {
    std::error_code fec;
    if (!fs::is_regular_file(it->symlink_status(fec))) continue;  // a link is not a second copy
    const uint64_t size = it->file_size(fec);
    if (!fec) total += size;
  }
  return total;
}

}  // namespace pf::server
