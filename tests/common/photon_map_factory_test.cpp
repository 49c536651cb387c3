// common/photon/photon_map_factory.h: every registered structure builds an empty map of its kind;
// an unknown name lists the known ones; each builder refuses an invalid option naming it; the
// registry's names are the `structure` setting's choices, and the kinds the same.

#include "common/photon/photon_map_factory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/photon/bucket_kdtree.h"
#include "common/photon/grid.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"
#include "tests/util/input_error.h"

namespace pf {
namespace {

using pf::testing::InputErrorOf;
using ::testing::HasSubstr;

TEST(PhotonMapFactory, NamesAndKindsAreTheStructureSettingsChoices) {
  std::vector<std::string> choices;
  for (const SettingChoice& c : FindRenderSetting("structure")->choices) choices.emplace_back(c.name);
  EXPECT_EQ(PhotonMapStructures().Names(), choices);
  for (const PhotonMapStructure& e : PhotonMapStructures().entries()) {
    JobRenderSettings s;
    SetRenderSetting(s, "structure", e.name, "structure");
    EXPECT_EQ(s.structure, e.kind) << e.name;
    EXPECT_EQ(&PhotonMapStructures().FindKind(e.kind), &e);
    EXPECT_EQ(&PhotonMapStructures().Find(e.name, "structure"), &e);
    EXPECT_EQ(CanSerialize(e.kind), e.serializable);
  }
}

// A setting that only some structures read (kd-split) applies exactly when the chosen structure's
// entry says it reads it: the table asks the entry, and UnusedSettings reports the rest.
TEST(PhotonMapFactory, StructureSettingsApplyWhereTheEntryReadsThem) {
  for (const PhotonMapStructure& e : PhotonMapStructures().entries()) {
    for (std::string_view name : e.settings) ASSERT_NE(FindRenderSetting(name), nullptr) << name;
    JobRenderSettings s;
    s.structure = e.kind;
    for (const PhotonMapStructure& other : PhotonMapStructures().entries())
      for (std::string_view name : other.settings) {
        EXPECT_EQ(FindRenderSetting(name)->applies(s), e.Reads(name)) << e.name << " " << name;
        EXPECT_EQ(UnusedSettings(s, {std::string(name)}).empty(), e.Reads(name)) << e.name << " " << name;
      }
  }
  EXPECT_TRUE(PhotonMapStructures().FindKind(PhotonMapKind::kKdTree).Reads("kd-split"));
}

TEST(PhotonMapFactory, EveryRegisteredNameBuildsItsStructure) {
  for (const PhotonMapStructure& e : PhotonMapStructures().entries()) {
    const std::unique_ptr<PhotonMap> map = e.build(PhotonMapOptions{});
    ASSERT_NE(map, nullptr) << e.name;
    EXPECT_EQ(map->size(), 0u);
  }
  EXPECT_NE(dynamic_cast<KdTree*>(MakePhotonMap(PhotonMapKind::kKdTree).get()), nullptr);
  EXPECT_NE(dynamic_cast<GridPhotonMap*>(MakePhotonMap(PhotonMapKind::kGrid).get()), nullptr);
  EXPECT_NE(dynamic_cast<BucketKdTree*>(MakePhotonMap(PhotonMapKind::kBucketKdTree).get()), nullptr);
}

TEST(PhotonMapFactory, UnknownNameListsTheKnownOnes) {
  EXPECT_THAT(
      InputErrorOf([] { PhotonMapStructures().Find("octree", "settings.structure"); }),
      HasSubstr("settings.structure: no photon-map structure is called 'octree' (known: kdtree, grid or "
                "bucket)"));
}

void ExpectRefused(PhotonMapKind kind, const PhotonMapOptions& o, const std::string& option) {
  EXPECT_THAT(InputErrorOf([&] { MakePhotonMap(kind, o); }), HasSubstr(option));
}

TEST(PhotonMapFactory, EachBuilderRefusesAnInvalidOptionNamingIt) {
  PhotonMapOptions o;
  o.grid.expected_k = 0;
  ExpectRefused(PhotonMapKind::kGrid, o, "expected_k");
  o = {};
  o.grid.photons_per_voxel = -1.0f;
  ExpectRefused(PhotonMapKind::kGrid, o, "photons_per_voxel");
  o = {};
  o.grid.max_voxels_per_photon = 0.0;
  ExpectRefused(PhotonMapKind::kGrid, o, "max_voxels_per_photon");
  o = {};
  o.bucket.leaf_size = 65;
  ExpectRefused(PhotonMapKind::kBucketKdTree, o, "leaf_size");
  // Each reads only its own options: the kd-tree builds with the others' invalid.
  o.grid.expected_k = 0;
  EXPECT_NE(MakePhotonMap(PhotonMapKind::kKdTree, o), nullptr);
}

}  // namespace
}  // namespace pf
