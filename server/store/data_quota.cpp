#include "server/store/data_quota.h"

namespace pf::server {
namespace fs = std::filesystem;

// Its own recursion rather than recursive_directory_iterator, whose walk ends at the first error:
// a folder that vanishes while it is walked (a map's pieces, an upload's temporary folder) would
// stop the count short, and the quota would see less than there is.
uint64_t DirectoryBytes(const fs::path& dir) {
  uint64_t total = 0;
  std::error_code ec;
  for (fs::directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end; it.increment(ec)) {
    std::error_code fec;
    const fs::file_status status = it->symlink_status(fec);  // a link is not a second copy
    if (fec) continue;
    if (fs::is_directory(status)) {
      total += DirectoryBytes(it->path());
    } else if (fs::is_regular_file(status)) {
      const uint64_t size = it->file_size(fec);
      if (!fec) total += size;
    }
  }
  return total;
}

}  // namespace pf::server
