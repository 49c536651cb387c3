// common/photon/photon_chunk.h: a map traced in pieces (any cut at multiples of the tracer's
// chunk, pieces through their byte form) and assembled is the map one process builds, photon for
// photon (and so renders bit-identically: tests/common/photon_maps_bytes_test.cpp renders
// identical maps identically); gaps and bad bytes are InputErrors.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "common/core/error.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon_chunk.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/plan/task_executor.h"
#include "common/scene/scene_loader.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

SceneDescription Shipped(const std::string& rel) {
  return LoadScene((std::filesystem::path(PF_SOURCE_DIR) / "scenes" / rel).string());
}

// The map bytes without the fields that legitimately differ (timings, float sum of the stored power).
std::string Comparable(PhotonMaps maps) {
  maps.stats.trace_seconds = maps.stats.build_seconds = 0;
  maps.stats.stored_power = Rgb(0.0f);
  return SerializePhotonMaps(maps);
}

// The Cornell box's map of 10000 photons, to trace pieces of.
struct CornellMap {
  CornellMap() {
    JobRenderSettings s;
    s.photons = 10000;
    options = s.Resolved(scene.description).MapsOptions();
  }
  PhotonChunk Trace(uint64_t begin, uint64_t end) const {
    return TracePhotonChunk(scene.accel, scene.lights, options, begin, end);
  }
  SceneRuntime scene{Shipped("cornell-box/cornell-box.json")};
  PhotonMapsOptions options;
};

TEST(PhotonChunk, PiecesAssembleToTheOneProcessMap) {
  struct Case {
    const char* scene;
    std::optional<DirectLightMode> direct;
    bool occlusion;
    uint32_t local_pass = 0;
  };
  // Monte Carlo direct light (auto on the Cornell box) without a local pass stores no direct map;
  // with the local pass it does (DirectMapRead).
  for (const Case& c : {Case{"cornell-box/cornell-box.json", std::nullopt, false},
                        Case{"cornell-box/cornell-box.json", DirectLightMode::kMonteCarlo, false, 2},
                        Case{"cornell-box/cornell-box.json", DirectLightMode::kPhotonDirect, true},
                        Case{"cornell-sphere/cornell-sphere.json", DirectLightMode::kNone, false}}) {
    SCOPED_TRACE(c.scene);
    const SceneRuntime scene(Shipped(c.scene));
    JobRenderSettings s;
    s.photons = 30001;  // the last piece ends off the 4096 grid
    s.direct = c.direct;
    s.occlusion_test = c.occlusion;
    s.local_pass_rays = c.local_pass;
    PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
    mo.tracing.map_seed = 99;
    mo.tracing.threads = 2;
    const PhotonMaps whole = PhotonMaps::Build(scene.accel, scene.lights, mo);
    for (const std::vector<uint64_t>& cuts :
         {std::vector<uint64_t>{0, 30001}, std::vector<uint64_t>{0, 4096, 8192, 30001},
          std::vector<uint64_t>{0, 12288, 28672, 30001}}) {
      std::vector<PhotonChunk> pieces;
      for (size_t i = 0; i + 1 < cuts.size(); ++i) {
        PhotonMapsOptions one = mo;
        one.tracing.threads = 1;  // a piece's photons do not depend on threads either
        pieces.push_back(DeserializePhotonChunk(
            SerializePhotonChunk(TracePhotonChunk(scene.accel, scene.lights, one, cuts[i], cuts[i + 1]))));
      }
      const PhotonMaps assembled = AssemblePhotonMaps(pieces, mo);
      EXPECT_EQ(Comparable(DeserializePhotonMaps(SerializePhotonMaps(assembled))),
                Comparable(DeserializePhotonMaps(SerializePhotonMaps(whole))))
          << cuts.size() - 1 << " pieces";
      EXPECT_EQ(assembled.stats.rays, whole.stats.rays);
      EXPECT_EQ(assembled.stats.emitted, whole.stats.emitted);
      EXPECT_EQ(assembled.stats.stored_global, whole.stats.stored_global);
      EXPECT_EQ(assembled.stats.stored_direct, whole.stats.stored_direct);
      if (cuts.size() == 2) {
        // One piece, as PhotonMaps::Build traces it: the stored power is the same sum, bit for bit.
        EXPECT_EQ(assembled.stats.stored_power.r, whole.stats.stored_power.r);
        EXPECT_EQ(assembled.stats.stored_power.b, whole.stats.stored_power.b);
      } else {
        EXPECT_NEAR(assembled.stats.stored_power.r, whole.stats.stored_power.r,
                    1e-5 * whole.stats.stored_power.r);
      }
    }
  }
}

// A photon is stored at every diffuse bounce: in the closed furnace (albedo 0.8) a piece's
// indirect list holds several photons per emitted one, and must still go through its byte form
// (a count bounded by the emitted photons refused every such upload; found by review).
TEST(PhotonChunk, MoreStoredThanEmittedGoesThroughTheByteForm) {
  const SceneRuntime scene(testing::FurnaceScene(0.8f));
  JobRenderSettings s;
  s.photons = 8192;
  PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
  const PhotonChunk piece = TracePhotonChunk(scene.accel, scene.lights, mo, 0, 4096);
  size_t most = 0;
  for (const PhotonChunk::List& l : piece.lists) most = std::max(most, l.photons.size());
  ASSERT_GT(most, 2 * 4096u) << "the furnace should store several photons per emitted one";
  const PhotonChunk back = DeserializePhotonChunk(SerializePhotonChunk(piece));
  for (size_t i = 0; i < piece.lists.size(); ++i) {
    ASSERT_EQ(back.lists[i].photons.size(), piece.lists[i].photons.size());
    EXPECT_EQ(std::memcmp(back.lists[i].photons.data(), piece.lists[i].photons.data(),
                          piece.lists[i].photons.size() * sizeof(Photon)),
              0);
  }
}

// What the trace counted travels with the piece (the coordinator's maps report what a local
// build reports): the counts through the byte form, summed by AssemblePhotonMaps; a piece that
// claims another number of emitted photons than its range is refused.
TEST(PhotonChunk, CountsTravelAndAreChecked) {
  const CornellMap map;
  const PhotonMapsOptions& mo = map.options;
  const PhotonChunk a = map.Trace(0, 8192);
  const PhotonChunk b = map.Trace(8192, 10000);
  EXPECT_EQ(a.counts.emitted, 8192u);
  EXPECT_EQ(b.counts.emitted, 10000u - 8192u);
  EXPECT_GT(a.counts.stored, 0u);
  EXPECT_GT(a.seconds, 0.0);
  const PhotonChunk back = DeserializePhotonChunk(SerializePhotonChunk(a));
  EXPECT_EQ(back.counts.emitted, a.counts.emitted);
  EXPECT_EQ(back.counts.stored, a.counts.stored);
  EXPECT_EQ(back.seconds, 0.0) << "a measurement, not part of the byte form";
  const PhotonMaps maps = AssemblePhotonMaps(std::vector<PhotonChunk>{back, b}, mo);
  EXPECT_EQ(maps.stats.emitted, 10000u);
  EXPECT_EQ(maps.stats.rays, a.rays + b.rays);
  PhotonChunk lying = b;
  lying.counts.emitted = 5000;
  EXPECT_THROW(AssemblePhotonMaps(std::vector<PhotonChunk>{a, lying}, mo), InputError);
}

TEST(PhotonChunk, GapsMisalignedCutsAndBadBytesAreErrors) {
  const CornellMap map;
  const PhotonMapsOptions& mo = map.options;
  const PhotonChunk a = map.Trace(0, 4096);
  const PhotonChunk c = map.Trace(8192, 10000);
  EXPECT_THROW(AssemblePhotonMaps(std::vector<PhotonChunk>{a, c}, mo), InputError);
  EXPECT_THROW(AssemblePhotonMaps(std::vector<PhotonChunk>{a}, mo), InputError);
  EXPECT_THROW(map.Trace(100, 4096), std::invalid_argument);
  const std::string bytes = SerializePhotonChunk(a);
  for (size_t n : {size_t(0), size_t(10), size_t(60), bytes.size() / 2, bytes.size() - 1}) {
    SCOPED_TRACE(n);
    EXPECT_THROW(DeserializePhotonChunk(std::string_view(bytes).substr(0, n)), InputError);
  }
  std::string bad = bytes;
  bad[12] = char(bad[12] ^ 1);  // begin (after the magic and version) no longer a multiple of 4096
  EXPECT_THROW(DeserializePhotonChunk(bad), InputError);
}

}  // namespace
}  // namespace pf
