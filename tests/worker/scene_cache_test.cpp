// worker/scene_cache.h: fetched once per cache directory, reused from memory and from disk
// (across worker restarts), verified by hash, and nothing but a hash becomes a path.
#include "worker/scene_cache.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "common/core/error.h"
#include "tests/util/temp_dir.h"

namespace pf::worker {
namespace {
namespace fs = std::filesystem;

SceneBundle CornellBundle() {
  return CollectBundle(fs::path(PF_SOURCE_DIR) / "scenes" / "cornell-box" / "cornell-box.json");
}

class SceneCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    bundle_ = CornellBundle();
    hash_ = BundleHash(bundle_);
  }
  SceneCache::Fetcher CountingFetcher(int* calls) {
    return [this, calls] {
      ++*calls;
      return bundle_;
    };
  }
  // Not created: the cache makes its own directory.
  test_util::TempDir tmp_{"pf-scene-cache"};
  const fs::path dir_ = tmp_.path() / "cache";
  SceneBundle bundle_;
  std::string hash_;
};

TEST_F(SceneCacheTest, FetchesOnceThenServesFromMemory) {
  SceneCache cache(dir_, 2);
  int calls = 0;
  std::string source;
  const auto a = cache.Get(hash_, CountingFetcher(&calls), &source);
  EXPECT_EQ(source, "fetched");
  const auto b = cache.Get(hash_, CountingFetcher(&calls), &source);
  EXPECT_EQ(source, "memory");
  EXPECT_EQ(a.get(), b.get());
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(a->description.NumTriangles(), 36u);
  EXPECT_EQ(cache.CachedHashes(), std::vector<std::string>{hash_});
}

TEST_F(SceneCacheTest, SurvivesARestartOnDisk) {
  int calls = 0;
  { SceneCache(dir_, 2).Get(hash_, CountingFetcher(&calls)); }
  SceneCache again(dir_, 2);
  EXPECT_EQ(again.CachedHashes(), std::vector<std::string>{hash_});  // found again after a restart
  std::string source;
  again.Get(hash_, CountingFetcher(&calls), &source);
  EXPECT_EQ(source, "disk");
  EXPECT_EQ(calls, 1);
}

TEST_F(SceneCacheTest, ACorruptedCopyIsFetchedAgain) {
  int calls = 0;
  { SceneCache(dir_, 2).Get(hash_, CountingFetcher(&calls)); }
  std::ofstream(dir_ / "scenes" / hash_ / "CornellBox-Original.mtl", std::ios::app) << "\n# edited\n";
  SceneCache again(dir_, 2);
  std::string source;
  again.Get(hash_, CountingFetcher(&calls), &source);
  EXPECT_EQ(source, "fetched");
  EXPECT_EQ(calls, 2);
}

TEST_F(SceneCacheTest, RejectsAWrongBundleAndMalformedHashes) {
  SceneCache cache(dir_, 2);
  int calls = 0;
  EXPECT_THROW(cache.Get(std::string(64, 'a'), CountingFetcher(&calls)), InputError);  // hash mismatch
  EXPECT_EQ(calls, 1);
  EXPECT_TRUE(cache.CachedHashes().empty());
  for (const std::string& bad :
       std::vector<std::string>{"../../etc", "", std::string(64, 'A'), std::string(63, 'a'), hash_ + "/x"})
    EXPECT_THROW(cache.Get(bad, CountingFetcher(&calls)), InputError) << bad;
  EXPECT_EQ(calls, 1);  // never fetched for a malformed hash
}

TEST_F(SceneCacheTest, EvictsTheLeastRecentlyUsedRuntime) {
  SceneCache cache(dir_, 1);
  SceneBundle other = bundle_;
  other.files.emplace_back("extra.txt", "another scene");
  const std::string other_hash = BundleHash(other);
  int calls = 0;
  std::string source;
  cache.Get(hash_, CountingFetcher(&calls));
  cache.Get(other_hash, [&] { return other; });
  cache.Get(hash_, CountingFetcher(&calls), &source);
  EXPECT_EQ(source, "disk");  // evicted from memory, still on disk
  EXPECT_EQ(calls, 1);
}

}  // namespace
}  // namespace pf::worker
