// common/photon/photon_maps_bytes.h: a built map written as bytes and read back answers every
// query as the original (the balanced arrays, axes and attributes are the same bytes, and a
// rendered task is bit-identical); truncated or corrupt bytes are an InputError, never a crash.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include "common/core/error.h"
#include "common/core/sha256.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/plan/task_executor.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

SceneDescription Shipped(const std::string& rel) {
  return LoadScene((std::filesystem::path(PF_SOURCE_DIR) / "scenes" / rel).string());
}

CameraSpec SmallCamera(const SceneDescription& d) {
  CameraSpec cam = d.cameras.empty() ? DefaultCamera(d) : d.cameras.front();
  cam.width = 24;
  cam.height = 16;
  return cam;
}

bool SamePhotons(const PhotonMap& a, const PhotonMap& b) {
  return a.size() == b.size() && (a.size() == 0 || std::memcmp(a.photons().data(), b.photons().data(),
                                                               a.size() * sizeof(Photon)) == 0);
}

void ExpectSameMaps(const PhotonMaps& a, const PhotonMaps& b) {
  ASSERT_EQ(bool(a.caustic), bool(b.caustic));
  ASSERT_EQ(bool(a.direct), bool(b.direct));
  EXPECT_TRUE(SamePhotons(*a.global, *b.global));
  if (a.caustic) {
    EXPECT_TRUE(SamePhotons(*a.caustic, *b.caustic));
  }
  if (a.direct) {
    EXPECT_TRUE(SamePhotons(*a.direct, *b.direct));
  }
  EXPECT_EQ(dynamic_cast<const KdTree&>(*a.global).stored_axes(),
            dynamic_cast<const KdTree&>(*b.global).stored_axes());
  EXPECT_EQ(a.direct_attributes.light, b.direct_attributes.light);
  EXPECT_EQ(a.global_attributes.origin.size(), b.global_attributes.origin.size());
  for (size_t i = 0; i < a.global_attributes.origin.size(); ++i)
    ASSERT_EQ(a.global_attributes.origin[i], b.global_attributes.origin[i]);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.stats.emitted, b.stats.emitted);
}

// Renders one task of the whole (small) image with `maps` as the cached maps of its seed.
std::vector<float> RenderWith(const SceneRuntime& scene, const JobRenderSettings& settings,
                              std::shared_ptr<const PhotonMaps> maps, const CameraSpec& cam) {
  PlanSpec plan;
  plan.samples_per_pixel = 2;
  const std::vector<TaskSpec> tasks = ExpandPlan(plan, cam.width, cam.height, 5);
  PhotonMapCache cache(1);
  const JobRenderSettings resolved = settings.Resolved(scene.description);
  EXPECT_EQ(maps->seed, tasks[0].map_seed);
  cache.Insert(MapCacheKey("s", resolved, tasks[0].map_seed), std::move(maps));
  const TaskOutput out = ExecuteTask(scene, "s", cam, settings, tasks[0], 2, &cache);
  EXPECT_TRUE(out.map_cache_hit);
  return out.rgb_sums;
}

struct Case {
  const char* scene;
  JobRenderSettings settings;
};

std::vector<Case> Cases() {
  std::vector<Case> cases;
  JobRenderSettings plain;  // Cornell box: widest-extent kd-tree, Monte Carlo direct (separate direct map)
  plain.photons = 20000;
  plain.k = 30;
  cases.push_back({"cornell-box/cornell-box.json", plain});
  JobRenderSettings attributes = plain;  // light ids (PhotonDirect) and origins (occlusion test)
  attributes.direct = DirectLightMode::kPhotonDirect;
  attributes.occlusion_test = true;
  attributes.kd_split = KdSplitRule::kLevelCycle;
  cases.push_back({"cornell-box/cornell-box.json", attributes});
  JobRenderSettings standalone = plain;  // caustic map, direct photons in the global map
  standalone.direct = DirectLightMode::kNone;
  cases.push_back({"cornell-sphere/cornell-sphere.json", standalone});
  return cases;
}

TEST(PhotonMapsBytes, RoundTripRendersBitIdentically) {
  for (const Case& c : Cases()) {
    SCOPED_TRACE(c.scene);
    const SceneRuntime scene(Shipped(c.scene));
    const CameraSpec cam = SmallCamera(scene.description);
    const JobRenderSettings resolved = c.settings.Resolved(scene.description);
    PhotonMapsOptions mo = resolved.MapsOptions();
    mo.tracing.map_seed = MapSeed(5, 0);
    mo.tracing.threads = 2;
    auto built = std::make_shared<const PhotonMaps>(PhotonMaps::Build(scene.accel, scene.lights, mo));
    const std::string bytes = SerializePhotonMaps(*built);
    EXPECT_EQ(SerializePhotonMaps(*built), bytes) << "deterministic";
    auto read = std::make_shared<const PhotonMaps>(DeserializePhotonMaps(bytes));
    ExpectSameMaps(*built, *read);
    EXPECT_EQ(SerializePhotonMaps(*read), bytes);
    const std::vector<float> a = RenderWith(scene, c.settings, built, cam);
    const std::vector<float> b = RenderWith(scene, c.settings, read, cam);
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size() * sizeof(float)), 0);
    // And equal to the task rendered without any cache (the map built inside ExecuteTask).
    PlanSpec plan;
    plan.samples_per_pixel = 2;
    const TaskOutput fresh =
        ExecuteTask(scene, "s", cam, c.settings, ExpandPlan(plan, cam.width, cam.height, 5)[0], 1);
    EXPECT_EQ(std::memcmp(a.data(), fresh.rgb_sums.data(), a.size() * sizeof(float)), 0);
  }
}

TEST(PhotonMapsBytes, TruncatedOrCorruptBytesAreInputErrors) {
  const SceneRuntime scene(Shipped("cornell-box/cornell-box.json"));
  JobRenderSettings s;
  s.photons = 5000;
  s.direct = DirectLightMode::kPhotonDirect;
  s.occlusion_test = true;
  PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
  mo.tracing.map_seed = 3;
  const std::string bytes = SerializePhotonMaps(PhotonMaps::Build(scene.accel, scene.lights, mo));
  ASSERT_GT(bytes.size(), 1000u);
  for (size_t n : {size_t(0), size_t(5), size_t(12), size_t(100), bytes.size() / 2, bytes.size() - 33,
                   bytes.size() - 1}) {
    SCOPED_TRACE(n);
    EXPECT_THROW(DeserializePhotonMaps(std::string_view(bytes).substr(0, n)), InputError);
  }
  for (size_t at : {size_t(0), size_t(9), size_t(20), size_t(150), bytes.size() / 3, bytes.size() - 1}) {
    SCOPED_TRACE(at);
    std::string bad = bytes;
    bad[at] = char(bad[at] ^ 0x40);
    EXPECT_THROW(DeserializePhotonMaps(bad), InputError);
  }
  EXPECT_THROW(DeserializePhotonMaps(bytes + "x"), InputError);
  try {
    DeserializePhotonMaps(std::string_view(bytes).substr(0, bytes.size() / 2));
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("photon maps:"), std::string::npos) << e.what();
  }
}

// The one reader of the trailer: the digest a file records is the SHA-256 of its content, read from
// bytes or from the file's end alike; ReadNamedPhotonMaps takes only the maps of the named digest
// and seed.
TEST(PhotonMapsBytes, TheTrailerNamesTheMaps) {
  const SceneRuntime scene(Shipped("cornell-box/cornell-box.json"));
  JobRenderSettings s;
  s.photons = 3000;
  PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
  mo.tracing.map_seed = 7;
  const std::string bytes = SerializePhotonMaps(PhotonMaps::Build(scene.accel, scene.lights, mo));
  const std::string digest = PhotonMapsDigest(bytes);
  EXPECT_EQ(digest, Sha256Hex(std::string_view(bytes).substr(0, bytes.size() - 32)));
  const std::filesystem::path file = std::filesystem::path(testing::TempDir()) / "trailer.pfmaps";
  {
    std::ofstream out(file, std::ios::binary);
    out << bytes;
  }
  EXPECT_EQ(PhotonMapsFileDigest(file), digest);
  std::filesystem::resize_file(file, 31);
  EXPECT_THROW(PhotonMapsFileDigest(file), InputError);
  std::filesystem::remove(file);
  EXPECT_THROW(PhotonMapsDigest("short"), InputError);

  const std::optional<PhotonMaps> read = ReadNamedPhotonMaps(bytes, digest, 7);
  ASSERT_TRUE(read);
  EXPECT_EQ(SerializePhotonMaps(*read), bytes);
  EXPECT_FALSE(ReadNamedPhotonMaps(bytes, digest, 8)) << "another seed";
  std::string other = digest;
  other[0] = other[0] == '0' ? '1' : '0';
  EXPECT_FALSE(ReadNamedPhotonMaps(bytes, other, 7)) << "another digest";
  EXPECT_FALSE(ReadNamedPhotonMaps(bytes, "", 7));
  std::string corrupt = bytes;
  corrupt[100] = char(corrupt[100] ^ 1);  // the trailer still names the digest: the content does not
  EXPECT_THROW(ReadNamedPhotonMaps(corrupt, digest, 7), InputError);
}

TEST(PhotonMapsBytes, OnlyKdTreesHaveAByteForm) {
  const SceneRuntime scene(Shipped("cornell-box/cornell-box.json"));
  JobRenderSettings s;
  s.photons = 2000;
  s.structure = PhotonMapKind::kGrid;
  PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
  const PhotonMaps grid = PhotonMaps::Build(scene.accel, scene.lights, mo);
  EXPECT_FALSE(CanSerialize(grid));
  EXPECT_FALSE(CanSerialize(PhotonMapKind::kBucketKdTree));
  EXPECT_THROW(SerializePhotonMaps(grid), std::logic_error);
}

}  // namespace
}  // namespace pf
