// PhotonMap::QueryRadius (photon_map.h), the range query of progressive photon mapping's pass
// estimate: every structure finds exactly the photons the brute force finds in the ball.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "common/core/rng.h"
#include "common/photon/brute_force.h"
#include "common/photon/photon_map_factory.h"

namespace pf {
namespace {

std::vector<uint32_t> Indices(std::span<const NearestPhotons::Entry> entries) {
  std::vector<uint32_t> v;
  for (const auto& e : entries) v.push_back(e.index);
  std::sort(v.begin(), v.end());
  return v;
}

TEST(RadiusQuery, EveryStructureFindsTheBruteForceBall) {
  Rng rng = Rng::ForKey(2011);
  std::vector<Photon> photons;
  // A clustered cloud: dense enough that a ball holds many times the first k of QueryRadius (64).
  for (int i = 0; i < 20000; ++i) {
    const Vec3 p(rng.Uniform(), rng.Uniform() * 0.2f, rng.Uniform() < 0.5f ? rng.Uniform() : 0.5f);
    photons.push_back(Photon::Make(p, Normalize(Vec3(0.3f, -1.0f, 0.2f)), Rgb(1.0f)));
  }
  const auto below = FunctionFilter([](const Photon& p, std::size_t) { return p.Position().y < 0.1f; });
  for (const PhotonMapKind kind :
       {PhotonMapKind::kKdTree, PhotonMapKind::kGrid, PhotonMapKind::kBucketKdTree}) {
    std::unique_ptr<PhotonMap> map = MakePhotonMap(kind);
    map->AddPhotons(photons);
    map->PrepareForQuery();
    NearestPhotons nearest;
    Rng q = Rng::ForKey(7);
    for (int i = 0; i < 200; ++i) {
      const Vec3 x(q.Uniform(), q.Uniform() * 0.2f, 0.5f);
      const float r = 0.005f + 0.2f * q.Uniform();
      const PhotonFilter* filter = i % 3 == 0 ? &below : nullptr;
      map->QueryRadius(x, r, nearest, filter);
      const auto expected = BruteForceNearest(map->photons(), x, int(map->size()), r, filter);
      ASSERT_EQ(Indices(nearest.entries()), Indices(expected)) << int(kind) << " query " << i;
      if (!nearest.empty()) {
        // The farthest first, as the radiance estimate expects.
        float far = 0;
        for (const auto& e : nearest.entries()) far = std::max(far, e.distance2);
        EXPECT_EQ(nearest[0].distance2, far);
      }
    }
    // A ball holding the whole map, and an empty one.
    map->QueryRadius(Vec3(0.5f), 10.0f, nearest);
    EXPECT_EQ(nearest.size(), photons.size());
    map->QueryRadius(Vec3(5.0f), 0.1f, nearest);
    EXPECT_TRUE(nearest.empty());
  }
}

}  // namespace
}  // namespace pf
