// common/photon/map_key.h: one key names a map in every cache — its text for the in-process cache,
// its address for the files — and each part of it (scene, settings, seed, build) changes both.
#include <gtest/gtest.h>

#include "common/photon/map_key.h"
#include "common/plan/task_executor.h"

namespace pf {
namespace {

TEST(MapKey, TextAndAddressChangeWithEveryPart) {
  const MapKey key{"scene", "photons=10", 3};
  EXPECT_EQ(key.Text(), "scene|photons=10|3");
  const std::string address = key.Address("1.0");
  EXPECT_TRUE(MapKey::IsAddress(address));
  EXPECT_EQ(key.Address("1.0"), address) << "deterministic";
  EXPECT_NE(key.Address("1.1"), address);
  EXPECT_NE((MapKey{"scene2", "photons=10", 3}.Address("1.0")), address);
  EXPECT_NE((MapKey{"scene", "photons=11", 3}.Address("1.0")), address);
  EXPECT_NE((MapKey{"scene", "photons=10", 4}.Address("1.0")), address);
  EXPECT_NE((MapKey{"scene", "photons=10", 4}.Text()), key.Text());
}

TEST(MapKey, AnAddressIsAFileNameNeverAPath) {
  EXPECT_TRUE(MapKey::IsAddress(std::string(64, 'a')));
  EXPECT_FALSE(MapKey::IsAddress(std::string(63, 'a')));
  EXPECT_FALSE(MapKey::IsAddress(std::string(64, 'A')));
  EXPECT_FALSE(MapKey::IsAddress("../" + std::string(61, 'a')));
}

// The in-process cache's key (MapCacheKey) is the key type's text of the resolved settings'
// fingerprint.
TEST(MapKey, TheCacheKeyIsTheKeyText) {
  JobRenderSettings s;
  s.photons = 1234;
  s.direct = DirectLightMode::kPhotonDirect;  // resolved: MapFingerprint needs it
  EXPECT_EQ(MapCacheKey("h", s, 9), (MapKey{"h", s.MapFingerprint(), 9}.Text()));
}

}  // namespace
}  // namespace pf
