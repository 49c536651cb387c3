// SinCos2Pi: the particle walks' polynomial azimuth (common/core/math.h), against double precision.
#include "common/core/math.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>

#include "common/core/rng.h"

namespace pf {
namespace {

// Every 24-bit uniform the samplers produce (k·2^-24; Sobol and Rng both give these) near the
// quadrant and octant boundaries, plus 2M random ones: |error| <= 2.5e-7 for sin and cos, the
// bound math.h states (a wrong coefficient, quadrant sign or swap is off by far more).
TEST(SinCos2Pi, MatchesDoublePrecision) {
  double worst = 0.0;
  auto check = [&](float u) {
    float s, c;
    SinCos2Pi(u, &s, &c);
    const double phi = 2.0 * std::numbers::pi * double(u);
    const double es = std::abs(double(s) - std::sin(phi)), ec = std::abs(double(c) - std::cos(phi));
    worst = std::max(worst, std::max(es, ec));
    ASSERT_LE(es, 2.5e-7) << "sin at u = " << u;
    ASSERT_LE(ec, 2.5e-7) << "cos at u = " << u;
  };
  for (int eighth = 0; eighth <= 8; ++eighth)
    for (int k = -2000; k <= 2000; ++k) {
      const int64_t i = int64_t(eighth) * (1 << 21) + k;  // (1 << 24) / 8 per eighth of a turn
      if (i >= 0 && i < (1 << 24)) check(float(i) * 0x1p-24f);
    }
  check(0x1.fffffep-1f);  // the largest float below 1
  check(1.0f);            // the end of the stated domain [0, 1]: a full turn
  Rng rng(5, 9);
  for (int i = 0; i < 2'000'000; ++i) check(rng.Uniform());
  RecordProperty("worst_abs_error", std::to_string(worst));
}

// The cosine lobe built on it: directions uniform in (z², azimuth) — the cosine-weighted density's
// two uniform coordinates — checked by their first moments over 1M random inputs (4σ):
// E[z] = 2/3, E[x] = E[y] = 0, E[x²] = E[y²] = 1/4, E[xy] = 0; a swapped or mis-signed quadrant
// moves E[x] or E[y] by ~0.1.
TEST(SinCos2Pi, CosineLobeHasTheCosineMoments) {
  constexpr int kN = 1'000'000;
  Rng rng(17, 3);
  double mx = 0, my = 0, mz = 0, mxx = 0, myy = 0, mxy = 0, mx_pos = 0;
  for (int i = 0; i < kN; ++i) {
    const Vec3 d = CosineHemisphereFast(rng.Uniform(), rng.Uniform());
    ASSERT_NEAR(Length(d), 1.0f, 1e-6f);
    mx += d.x;
    my += d.y;
    mz += d.z;
    mxx += d.x * d.x;
    myy += d.y * d.y;
    mxy += d.x * d.y;
    mx_pos += d.x > 0 && d.y > 0;  // first quadrant of the azimuth: 1/4 of the samples
  }
  const double n = kN;
  EXPECT_NEAR(mz / n, 2.0 / 3.0, 4 * std::sqrt(1.0 / 18.0 / n));  // Var z = 1/2 − 4/9
  EXPECT_NEAR(mx / n, 0.0, 4 * std::sqrt(0.25 / n));
  EXPECT_NEAR(my / n, 0.0, 4 * std::sqrt(0.25 / n));
  EXPECT_NEAR(mxx / n, 0.25, 4 * std::sqrt(0.125 / n));  // E[x⁴] = 1/8 bounds the variance
  EXPECT_NEAR(myy / n, 0.25, 4 * std::sqrt(0.125 / n));
  EXPECT_NEAR(mxy / n, 0.0, 4 * std::sqrt(0.125 / n));
  EXPECT_NEAR(mx_pos / n, 0.25, 4 * std::sqrt(0.1875 / n));
}

}  // namespace
}  // namespace pf
