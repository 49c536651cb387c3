// worker/map_disk_cache.h on real files: maps come back as written, the least recently used go
// first when the size limit is passed (Get counts as use), keys are never paths, leftovers of
// interrupted writes are removed at start-up.
#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "tests/util/temp_dir.h"
#include "worker/map_disk_cache.h"

namespace pf::worker {
namespace {

std::string Key(char c) {
  return std::string(64, c);
}

TEST(MapDiskCache, KeepsMapsWithinTheLimitLeastRecentlyUsedFirst) {
  test_util::TempDir dir("pf_worker_test");
  MapDiskCache cache(dir.path() / "maps", 250);
  cache.Put(Key('a'), std::string(100, 'A'));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // distinct modification times
  cache.Put(Key('b'), std::string(100, 'B'));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(cache.Get(Key('a')), std::string(100, 'A'));  // a is now the most recently used
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  cache.Put(Key('c'), std::string(100, 'C'));  // 300 > 250: b goes
  EXPECT_FALSE(cache.Get(Key('b')).has_value());
  EXPECT_EQ(cache.Get(Key('a')), std::string(100, 'A'));
  EXPECT_EQ(cache.Get(Key('c')), std::string(100, 'C'));
  EXPECT_EQ(cache.total_bytes(), 200u);
  cache.Put(Key('d'), std::string(300, 'D'));  // larger than the limit: not kept, nothing evicted
  EXPECT_FALSE(cache.Get(Key('d')).has_value());
  EXPECT_EQ(cache.total_bytes(), 200u);
  cache.Remove(Key('a'));
  EXPECT_FALSE(cache.Get(Key('a')).has_value());
}

TEST(MapDiskCache, KeysAreContentAddressesNotPaths) {
  test_util::TempDir dir("pf_worker_test");
  MapDiskCache cache(dir.path() / "maps", 1000);
  EXPECT_THROW(cache.Get("../../etc/passwd"), std::invalid_argument);
  EXPECT_THROW(cache.Put(std::string(64, 'A'), "x"), std::invalid_argument);  // upper case
  EXPECT_THROW(cache.Put(std::string(63, 'a'), "x"), std::invalid_argument);
}

TEST(MapDiskCache, InterruptedWritesAreRemovedAtStartUp) {
  test_util::TempDir dir("pf_worker_test");
  std::filesystem::create_directories(dir.path() / "maps");
  const auto leftover = dir.path() / "maps" / (".x.pfmaps.tmp-1-1");
  std::ofstream(leftover) << "partial";
  MapDiskCache cache(dir.path() / "maps", 1000);
  EXPECT_FALSE(std::filesystem::exists(leftover));
}

}  // namespace
}  // namespace pf::worker
