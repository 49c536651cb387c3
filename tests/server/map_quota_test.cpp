// The map store's quota (server/scheduling/map_quota.h; docs/farm.md "The map store's quota"): the
// least recently used maps go first, a live map never, and the store ends at or under the quota
// when it can; a map served (MapFile) counts as used; a quota only live maps exceed keeps them.
#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/map_quota.h"
#include "server/scheduling/map_store_files.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using testing::MakeConfig;
using testing::MultipleMaps;
namespace fs = std::filesystem;

std::vector<std::string> Keys(const std::vector<StoredMap>& maps) {
  std::vector<std::string> keys;
  for (const StoredMap& m : maps) keys.push_back(m.key);
  return keys;
}

TEST(ChooseEvictions, LeastRecentlyUsedFirstUntilUnderTheQuotaSkippingLiveMaps) {
  const std::vector<StoredMap> stored = {
      {"d", 100, 40}, {"a", 100, 10}, {"c", 100, 30}, {"b", 100, 20}, {"e", 100, 50}};
  auto none = [](const std::string&) { return false; };
  QuotaChoice c = ChooseEvictions(stored, 500, 500, none);
  EXPECT_TRUE(c.evict.empty()) << "at the quota: nothing goes";
  EXPECT_TRUE(c.met);
  c = ChooseEvictions(stored, 500, 250, none);
  EXPECT_EQ(Keys(c.evict), (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(c.bytes_after, 200u);
  EXPECT_TRUE(c.met);
  c = ChooseEvictions(stored, 500, 250, [](const std::string& k) { return k == "a" || k == "c"; });
  EXPECT_EQ(Keys(c.evict), (std::vector<std::string>{"b", "d", "e"})) << "live maps are passed over";
  EXPECT_EQ(c.bytes_after, 200u);
  // Files no map names count in the total: more has to go.
  c = ChooseEvictions(stored, 560, 500, none);
  EXPECT_EQ(Keys(c.evict), (std::vector<std::string>{"a"}));
  EXPECT_EQ(c.bytes_after, 460u);
  // Only live maps left over the quota: what can go goes, the quota is not met.
  c = ChooseEvictions(stored, 500, 150, [](const std::string& k) { return k != "e"; });
  EXPECT_EQ(Keys(c.evict), (std::vector<std::string>{"e"}));
  EXPECT_EQ(c.bytes_after, 400u);
  EXPECT_FALSE(c.met);
  // Equal times: by key, so the choice is repeatable.
  c = ChooseEvictions({{"y", 10, 5}, {"x", 10, 5}}, 20, 10, none);
  EXPECT_EQ(Keys(c.evict), (std::vector<std::string>{"x"}));
}

class MapQuotaStoreTest : public ::testing::Test {
 protected:
  static JobConfig Config(uint32_t maps, uint64_t seed) {
    JobConfig c = MakeConfig(MultipleMaps(maps, 0), 16, 16);
    c.seed = seed;
    c.settings.photons = 40000;
    c.settings.map_tracing = MapTracingMode::kDistributed;
    return c;
  }
  // A built map of `bytes` bytes (and its 3-byte record), last used `age` seconds ago.
  void Store(const std::string& key, size_t bytes, int age) {
    const fs::path f = MapFileOf(maps_dir_, key);
    std::ofstream(f) << std::string(bytes, 'm');
    std::ofstream(TracersFile(f)) << "w1\n";
    const auto t = fs::file_time_type::clock::now() - std::chrono::seconds(age);
    fs::last_write_time(f, t);
    fs::last_write_time(TracersFile(f), t);
  }
  testing::TempDir dir_;
  FakeClock clock_;
  fs::path maps_dir_ = dir_.path() / "maps";
};

TEST_F(MapQuotaStoreTest, TheStoreListsMapsByKeyWithTheirBytesAndLastUse) {
  fs::create_directories(maps_dir_ / (std::string(64, 'a') + ".chunks"));
  Store(std::string(64, 'b'), 100, 50);
  std::ofstream(maps_dir_ / (std::string(64, 'a') + ".chunks") / "0-4096") << "12345";
  std::ofstream(maps_dir_ / "notes.txt") << "123";
  uint64_t total = 0;
  const std::vector<StoredMap> maps = ListStoredMaps(maps_dir_.string(), &total);
  ASSERT_EQ(maps.size(), 2u);
  EXPECT_EQ(maps[0].key, std::string(64, 'a'));
  EXPECT_EQ(maps[0].bytes, 5u);
  EXPECT_EQ(maps[1].bytes, 103u);
  EXPECT_LT(maps[1].last_used_ns, maps[0].last_used_ns);
  EXPECT_EQ(total, 111u) << "every file counts";
}

TEST_F(MapQuotaStoreTest, ALiveJobsMapsStayTheLeastRecentlyUsedOthersGoAndServingIsAUse) {
  const auto live = std::make_shared<const JobConfig>(Config(2, 1));
  const auto done = std::make_shared<const JobConfig>(Config(4, 2));
  fs::create_directories(maps_dir_);
  // The live job's maps are the oldest; the finished job's map 3 is the newest.
  Store(DistributedMapKey(*live, MapSeed(1, 0)), 1000, 500);
  Store(DistributedMapKey(*live, MapSeed(1, 1)), 1000, 400);
  for (int i = 0; i < 4; ++i) Store(DistributedMapKey(*done, MapSeed(2, i)), 1000, 300 - 50 * i);
  const std::string orphan(64, 'c');  // on disk, no job knows it
  Store(orphan, 1000, 10);

  DistributedMaps maps({.dir = maps_dir_, .quota_bytes = 4 * 1003}, clock_,
                       [](const std::string&) { return fs::path(); });
  // Map 2 of the finished job is served: now the most recently used.
  ASSERT_TRUE(maps.MapFile(DistributedMapKey(*done, MapSeed(2, 2))).has_value());
  const std::vector<Scheduler::KnownJob> jobs = {{"live", live, true}, {"done", done, false}};
  DistributedMaps::Evicted e = maps.EnforceQuota(jobs);
  EXPECT_EQ(e.maps, 3u);
  EXPECT_EQ(e.bytes, 3 * 1003u);
  EXPECT_EQ(e.bytes_after, 4 * 1003u);
  EXPECT_TRUE(e.met);
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*live, MapSeed(1, 0)))));
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*live, MapSeed(1, 1)))));
  EXPECT_FALSE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*done, MapSeed(2, 0)))));
  EXPECT_FALSE(fs::exists(TracersFile(MapFileOf(maps_dir_, DistributedMapKey(*done, MapSeed(2, 0))))));
  EXPECT_FALSE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*done, MapSeed(2, 1)))));
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*done, MapSeed(2, 2))))) << "served: used";
  EXPECT_FALSE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*done, MapSeed(2, 3)))));
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir_, orphan)));
  EXPECT_FALSE(maps.MapFile(DistributedMapKey(*done, MapSeed(2, 0))).has_value()) << "no longer served";
  EXPECT_EQ(maps.counters().maps_evicted, 3u);
  EXPECT_EQ(maps.counters().bytes_evicted, 3 * 1003u);
}

TEST_F(MapQuotaStoreTest, AQuotaOnlyLiveMapsExceedKeepsThemUntilTheirJobEnds) {
  const auto live = std::make_shared<const JobConfig>(Config(3, 1));
  const auto done = std::make_shared<const JobConfig>(Config(1, 2));
  fs::create_directories(maps_dir_);
  for (int i = 0; i < 3; ++i) Store(DistributedMapKey(*live, MapSeed(1, i)), 1000, 100 + i);
  Store(DistributedMapKey(*done, MapSeed(2, 0)), 1000, 1);
  DistributedMaps maps({.dir = maps_dir_, .quota_bytes = 1500}, clock_,
                       [](const std::string&) { return fs::path(); });
  DistributedMaps::Evicted e = maps.EnforceQuota({{"live", live, true}, {"done", done, false}});
  EXPECT_EQ(e.maps, 1u) << "only the finished job's map";
  EXPECT_FALSE(e.met);
  EXPECT_EQ(e.bytes_after, 3 * 1003u);
  for (int i = 0; i < 3; ++i)
    EXPECT_TRUE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*live, MapSeed(1, i)))));
  // The same job finished: now its maps go, oldest first, until the store is under the quota.
  const std::vector<Scheduler::KnownJob> finished = {Scheduler::KnownJob{"live", live, false}};
  e = maps.EnforceQuota(finished);
  EXPECT_EQ(e.maps, 2u);
  EXPECT_TRUE(e.met);
  EXPECT_TRUE(fs::exists(MapFileOf(maps_dir_, DistributedMapKey(*live, MapSeed(1, 0)))))
      << "the most recently used (stored 100 s ago; the others 101 and 102)";
}

}  // namespace
}  // namespace pf::server
