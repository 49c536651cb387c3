// The data dir's measure (server/store/data_quota.h).
#include "server/store/data_quota.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/util/temp_dir.h"

namespace pf::server {
namespace {
namespace fs = std::filesystem;

TEST(DataQuota, DirectoryBytesCountsEveryRegularFileBelowTheFolder) {
  test_util::TempDir dir("pf_server_test");
  EXPECT_EQ(DirectoryBytes(dir.path()), 0u);
  EXPECT_EQ(DirectoryBytes(dir.path() / "missing"), 0u);
  std::ofstream(dir.path() / "coordinator.db") << std::string(1000, 'a');
  fs::create_directories(dir.path() / "maps" / "k.chunks");
  std::ofstream(dir.path() / "maps" / "k.chunks" / "0-65536") << std::string(250, 'b');
  std::ofstream(dir.path() / "maps" / "k.pfmaps") << std::string(4096, 'c');
  fs::create_symlink(dir.path() / "maps" / "k.pfmaps", dir.path() / "link");  // not a second copy
  EXPECT_EQ(DirectoryBytes(dir.path()), 1000u + 250u + 4096u);
}

}  // namespace
}  // namespace pf::server
