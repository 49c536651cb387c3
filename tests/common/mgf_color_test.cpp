// MGF colour (common/scene/mgf_color.h, mgfdoc.tr §6.1.1): the XYZ -> RGB matrix is checked
// against the RGB -> XYZ map built here from the spec's primaries and white point, and black
// bodies against published Planckian-locus chromaticities (CIE 1931 2°). mgf_loader_test.cpp
// checks the same conversions through MGF files.

#include "common/scene/mgf_color.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <vector>

namespace pf::mgf {
namespace {

// RGB -> XYZ for the §6.1.1 primaries (0.640,0.330) (0.290,0.600) (0.150,0.060) and
// equal-energy white: columns are the primaries' XYZ per unit luminance, scaled so that
// r = g = b = 1 gives X = Y = Z = 1. Solved here by Cramer's rule, independently of the loader.
std::array<Vec3d, 3> RgbToXyzColumns() {
  const double xs[3] = {0.640, 0.290, 0.150}, ys[3] = {0.330, 0.600, 0.060};
  Vec3d c[3];
  for (int i = 0; i < 3; ++i) c[i] = {xs[i] / ys[i], 1.0, (1.0 - xs[i] - ys[i]) / ys[i]};
  const Vec3d white{1, 1, 1};
  const double det = Dot(c[0], Cross(c[1], c[2]));
  const double s0 = Dot(white, Cross(c[1], c[2])) / det;
  const double s1 = Dot(c[0], Cross(white, c[2])) / det;
  const double s2 = Dot(c[0], Cross(c[1], white)) / det;
  return {c[0] * s0, c[1] * s1, c[2] * s2};
}

TEST(MgfColor, CieToRgbInvertsThePrimariesMatrix) {
  const auto m = RgbToXyzColumns();
  // In-gamut chromaticities at several luminances: RGB -> XYZ must give the input back.
  for (const auto& [x, y, Y] : std::vector<std::array<double, 3>>{
           {1.0 / 3.0, 1.0 / 3.0, 1.0}, {0.3127, 0.3290, 0.5}, {0.45, 0.41, 2.0}, {0.25, 0.35, 0.1}}) {
    const Rgb rgb = CieToRgb(x, y, Y);
    ASSERT_GT(std::min({rgb.r, rgb.g, rgb.b}), 0.0f) << "expected in gamut: " << x << ", " << y;
    const Vec3d xyz = m[0] * double(rgb.r) + m[1] * double(rgb.g) + m[2] * double(rgb.b);
    EXPECT_NEAR(xyz.y, Y, 1e-6 * Y);
    EXPECT_NEAR(xyz.x / (xyz.x + xyz.y + xyz.z), x, 1e-6);
    EXPECT_NEAR(xyz.y / (xyz.x + xyz.y + xyz.z), y, 1e-6);
  }
}

TEST(MgfColor, EqualEnergyWhiteIsGreyAndPrimariesArePureChannels) {
  const Rgb w = CieToRgb(1.0 / 3.0, 1.0 / 3.0, 0.25);
  EXPECT_NEAR(w.r, 0.25f, 1e-6f);
  EXPECT_NEAR(w.g, 0.25f, 1e-6f);
  EXPECT_NEAR(w.b, 0.25f, 1e-6f);
  const Rgb g = CieToRgb(0.290, 0.600, 1.0);
  EXPECT_GT(g.g, 0.5f);
  EXPECT_NEAR(g.r, 0.0f, 1e-6f);
  EXPECT_NEAR(g.b, 0.0f, 1e-6f);
  const Rgb b = CieToRgb(0.150, 0.060, 1.0);
  EXPECT_GT(b.b, 1.0f);
  EXPECT_NEAR(b.r, 0.0f, 1e-6f);
  EXPECT_NEAR(b.g, 0.0f, 1e-6f);
  // Spectral green at 520 nm is outside the primaries' triangle: red would be negative and is
  // clamped to 0 (§6.1.1 "watch for negative values"). No luminance-carrying y: black.
  const Rgb spectral = CieToRgb(0.0743, 0.8338, 1.0);
  EXPECT_EQ(spectral.r, 0.0f);
  EXPECT_GT(spectral.g, 0.0f);
  EXPECT_EQ(CieToRgb(0.3, 0.0, 1.0).Max(), 0.0f);
  // The unnamed colour is that white at Y = 1.
  const Rgb grey = ChromaRgb(Chroma{});
  EXPECT_NEAR(grey.r, 1.0f, 1e-6f);
  EXPECT_NEAR(grey.g, 1.0f, 1e-6f);
  EXPECT_NEAR(grey.b, 1.0f, 1e-6f);
}

TEST(MgfColor, XyzToChromaNormalisesAndRejectsColoursWithoutLuminance) {
  Chroma c;
  ASSERT_TRUE(XyzToChroma({2, 2, 2}, &c));
  EXPECT_DOUBLE_EQ(c.x, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.y, 1.0 / 3.0);
  // XyzPerLuminance is the inverse at Y = 1.
  const Chroma warm{0.4476, 0.4074};
  const Vec3d xyz = warm.XyzPerLuminance();
  EXPECT_EQ(xyz.y, 1.0);
  ASSERT_TRUE(XyzToChroma(xyz * 7.0, &c));
  EXPECT_NEAR(c.x, warm.x, 1e-12);
  EXPECT_NEAR(c.y, warm.y, 1e-12);
  EXPECT_FALSE(XyzToChroma({1, 0, 1}, &c));                  // no luminance
  EXPECT_FALSE(XyzToChroma({-5, 1, 1}, &c));                 // negative sum
  EXPECT_FALSE(XyzToChroma({1, 0.5 * kMinChromaY, 0}, &c));  // y below the spectral locus
}

TEST(MgfColor, BlackBodiesLandOnThePlanckianLocus) {
  // CIE 1931 2° chromaticities of Planckian radiators (CIE 15:2004 tables); the 10 nm colour-
  // matching functions agree to a few 1e-4.
  struct Point {
    double kelvin, x, y;
  };
  for (const Point& p :
       {Point{2856, 0.4476, 0.4074}, Point{6500, 0.3135, 0.3236}, Point{10000, 0.2807, 0.2884}}) {
    Chroma c;
    ASSERT_TRUE(BlackbodyToChroma(p.kelvin, &c)) << p.kelvin;
    EXPECT_NEAR(c.x, p.x, 0.001) << p.kelvin << " K";
    EXPECT_NEAR(c.y, p.y, 0.001) << p.kelvin << " K";
  }
  // At 1 K nothing is emitted in 380-780 nm (the exponential overflows): no colour.
  Chroma c;
  EXPECT_FALSE(BlackbodyToChroma(1.0, &c));
}

TEST(MgfColor, SpectrumToXyNeedsTwoSamplesAndAnIncreasingRange) {
  const double v[3] = {1, 1, 1};
  double x = -1, y = -1;
  EXPECT_FALSE(SpectrumToXy(400, 700, v, 1, &x, &y));
  EXPECT_FALSE(SpectrumToXy(700, 400, v, 3, &x, &y));
  EXPECT_FALSE(SpectrumToXy(800, 900, v, 3, &x, &y));  // outside the visible range
  EXPECT_EQ(x, -1.0);
  ASSERT_TRUE(SpectrumToXy(400, 700, v, 3, &x, &y));
  EXPECT_GT(x, 0.0);
}

}  // namespace
}  // namespace pf::mgf
