// The radius schedule of progressive photon mapping (Knaus & Zwicker 2011, eq. 13;
// common/render/progressive_radius.h).
#include "common/render/progressive_radius.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "common/render/job_render_settings.h"

namespace pf {
namespace {

TEST(ProgressiveRadius, FollowsKnausZwickerEquation13) {
  const double a = 2.0 / 3.0;
  EXPECT_EQ(ProgressiveRadiusFactor2(a, 0), 1.0);
  // r_{i+1}² = r_i² (i + α)/(i + 1) with the paper's 1-based i: pass 1 (0-based) is (1 + α)/2.
  EXPECT_DOUBLE_EQ(ProgressiveRadiusFactor2(a, 1), (1 + a) / 2);
  EXPECT_DOUBLE_EQ(ProgressiveRadiusFactor2(a, 2), (1 + a) / 2 * (2 + a) / 3);
  for (uint64_t p = 1; p < 300; ++p)
    EXPECT_DOUBLE_EQ(ProgressiveRadiusFactor2(a, p) / ProgressiveRadiusFactor2(a, p - 1),
                     (double(p) + a) / double(p + 1));
  // r_p² ∝ p^(α−1) asymptotically (the product is Γ(p+1+α)/(Γ(1+α) Γ(p+2))): the log-log slope
  // between passes 1000 and 4000 is α − 1.
  const double slope = std::log(ProgressiveRadiusFactor2(a, 4000) / ProgressiveRadiusFactor2(a, 1000)) /
                       std::log(4000.0 / 1000.0);
  EXPECT_NEAR(slope, a - 1, 1e-3);
  // α → 1 would keep the radius.
  EXPECT_NEAR(ProgressiveRadiusFactor2(0.999999, 50), 1.0, 1e-4);
}

TEST(ProgressiveRadius, InitialRadiusHoldsAboutKPhotonsOfAnEvenlyLitBox) {
  Bounds3 box;
  box.Extend(Vec3(0.0f, 0.0f, 0.0f));
  box.Extend(Vec3(2.0f, 1.0f, 3.0f));
  const double area = 2 * (2 * 1 + 1 * 3 + 3 * 2);
  const double r = DerivedInitialRadius(box, 100000, 50);
  EXPECT_NEAR(std::numbers::pi * r * r * 100000 / area, 50.0, 1e-6);
  // Four times the photons: half the radius.
  EXPECT_NEAR(DerivedInitialRadius(box, 400000, 50), r / 2, 1e-9);
  // An empty scene still has a positive radius.
  EXPECT_GT(DerivedInitialRadius(Bounds3{}, 1000, 50), 0.0);
}

TEST(ProgressiveRadius, PassRadiusUsesTheSettingOrTheDerivedOne) {
  Bounds3 box;
  box.Extend(Vec3(0.0f));
  box.Extend(Vec3(1.0f));
  JobRenderSettings s;
  s.photons = 10000;
  s.k = 20;
  const float derived = float(DerivedInitialRadius(box, s.photons, s.k));
  EXPECT_FLOAT_EQ(ProgressivePassRadius(s, box, 0), derived);
  s.progressive_radius = 0.5f;
  s.progressive_alpha = 0.5;
  EXPECT_FLOAT_EQ(ProgressivePassRadius(s, box, 0), 0.5f);
  EXPECT_FLOAT_EQ(ProgressivePassRadius(s, box, 3), float(0.5 * std::sqrt(ProgressiveRadiusFactor2(0.5, 3))));
  EXPECT_LT(ProgressivePassRadius(s, box, 4), ProgressivePassRadius(s, box, 3));
}

}  // namespace
}  // namespace pf
