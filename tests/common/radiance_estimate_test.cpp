// The radiance estimate (Wald 1999, §2.5) with a maximum search radius: where fewer than k
// photons lie within it, the disk searched is the area, not the farthest photon's disk.
#include "common/estimators/radiance_estimate.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/core/rng.h"
#include "common/photon/photon_map_factory.h"

namespace pf {
namespace {

TEST(RadianceEstimate, BoundedQueryWithFewerThanKDividesByTheSearchedDisk) {
  // Photons uniform on a 100 x 100 plane, λ = 20 per unit area, Φ = 0.5 each; a Lambertian
  // surface with ρ = 1 reflects L = (1/π)·λΦ. R holds 20 photons on average, k = 1000 is never
  // reached. Dividing by the n-th photon's disk instead would be n/(n−1) ≈ 5 % high.
  constexpr double kSide = 100, kLambda = 20, kPower = 0.5;
  Rng rng(17, 3);
  std::vector<Photon> photons;
  for (int i = 0; i < int(kSide * kSide * kLambda); ++i)
    photons.push_back(Photon::Make(Vec3(float(kSide * rng.Uniform()), float(kSide * rng.Uniform()), 0.0f),
                                   Vec3(0, 0, 1), Rgb(float(kPower))));
  auto map = MakePhotonMap(PhotonMapKind::kKdTree);
  map->AddPhotons(photons);
  map->PrepareForQuery();

  Material white;
  white.diffuse_reflectance = Rgb(1.0f);
  const Bsdf bsdf(white, Vec3(0, 0, 1), Vec3(0, 0, 1));
  RadianceEstimateOptions o;
  o.k = 1000;
  o.max_radius = float(std::sqrt(20.0 / (kPi * kLambda)));
  o.direction_test = FeasibilityTest::kNone;
  NearestPhotons nearest;
  double sum = 0;
  constexpr int kQueries = 4000;
  for (int q = 0; q < kQueries; ++q) {
    const Vec3 x(float(5 + 90 * rng.Uniform()), float(5 + 90 * rng.Uniform()), 0.0f);
    const RadianceEstimateResult r =
        EstimateRadiance(*map, bsdf, x, Vec3(0, 0, 1), kLobeDiffuseReflection, o, nearest);
    ASSERT_LT(r.photons_used, o.k);
    ASSERT_FLOAT_EQ(r.radius2, o.max_radius * o.max_radius);
    sum += r.radiance.Mean();
  }
  const double expected = kLambda * kPower / kPi;
  // Standard error of the mean: ≈ 22 % / √4000 per query (Poisson counts of 20) ≈ 0.4 %,
  // plus the photon set's own fluctuation; 1.5 % is > 3σ and well below the 5 % bias.
  EXPECT_NEAR(sum / kQueries, expected, 0.015 * expected);
}

}  // namespace
}  // namespace pf
