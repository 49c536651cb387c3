// The masked metrics of pf diff (docs/renderer.md, "Sampling and determinism"): where emitters are seen
// directly (common/render/emitter_coverage.h), the exclusion band around them, rmse_masked and rmse_lowfreq
// (common/image/image_diff.h), checked against hand-computed values.
#include "common/render/emitter_coverage.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/core/error.h"
#include "common/image/image_diff.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

// An emitter on the left half (x < 0) of the plane z = 0 and a grey wall on the right half, seen
// head-on from z = 5 with a 90° field of view: world x = 0 is the image's vertical centre line.
SceneDescription HalfEmitterScene(bool emitter_faces_camera) {
  SceneDescription s;
  Material light;
  light.emission = Rgb(5.0f);
  Material grey;
  grey.diffuse_reflectance = Rgb(0.5f);
  const uint32_t ml = testing::AddMaterial(s, light), mg = testing::AddMaterial(s, grey);
  if (emitter_faces_camera)
    testing::AddQuad(s, {-10, -10, 0}, {0, -10, 0}, {0, 10, 0}, {-10, 10, 0}, ml, 0);
  else
    testing::AddQuad(s, {-10, -10, 0}, {-10, 10, 0}, {0, 10, 0}, {0, -10, 0}, ml, 0);
  testing::AddQuad(s, {0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}, mg);
  s.num_lights = 1;
  return s;
}

Camera HeadOnCamera(int width, int height) {
  return Camera(testing::LookAtCamera(Vec3(0, 0, 5), Vec3(0, 0, 0), Vec3(0, 1, 0), 90.0f, width, height));
}

TEST(EmitterCoverage, IsOneWhereTheCameraSeesTheFrontOfAnEmitterAndZeroElsewhere) {
  const SceneDescription scene = HalfEmitterScene(true);
  const EmbreeScene accel(scene);
  const std::vector<float> c = EmitterCoverage(accel, HeadOnCamera(8, 8));
  ASSERT_EQ(c.size(), 64u);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) EXPECT_EQ(c[y * 8 + x], x < 4 ? 1.0f : 0.0f) << x << "," << y;
  // An odd width puts the light's border through the middle column: half covered.
  const std::vector<float> odd = EmitterCoverage(accel, HeadOnCamera(7, 7));
  for (int y = 0; y < 7; ++y) {
    EXPECT_EQ(odd[y * 7 + 2], 1.0f);
    EXPECT_EQ(odd[y * 7 + 3], 0.5f);
    EXPECT_EQ(odd[y * 7 + 4], 0.0f);
  }
}

TEST(EmitterCoverage, TheBackOfAOneSidedEmitterDoesNotCount) {
  const SceneDescription scene = HalfEmitterScene(false);
  const EmbreeScene accel(scene);
  for (float v : EmitterCoverage(accel, HeadOnCamera(8, 8))) EXPECT_EQ(v, 0.0f);
}

TEST(EmitterExclusionMask, CoversEmitterPixelsAndABandOfTwoPixelsClippedAtTheBorder) {
  std::vector<float> coverage(10 * 6, 0.0f);
  coverage[1 * 10 + 1] = 0.25f;  // (1, 1)
  const std::vector<uint8_t> m = EmitterExclusionMask(coverage, 10, 6);
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 10; ++x) EXPECT_EQ(m[y * 10 + x], x <= 3 && y <= 3 ? 1 : 0) << x << "," << y;
  EXPECT_THROW(EmitterExclusionMask(coverage, 6, 6), InputError);
}

TEST(ImageDiffMasked, HandComputedMaskedAndLowFrequencyRmse) {
  // 12 x 8: the mask covers [0,3] x [0,3] (an emitter pixel at (1,1)), leaving 80 pixels and the
  // five 4 x 4 blocks at (4,0), (8,0), (0,4), (4,4), (8,4).
  const int w = 12, h = 8;
  std::vector<float> coverage(w * h, 0.0f);
  coverage[1 * w + 1] = 1.0f;
  const std::vector<uint8_t> mask = EmitterExclusionMask(coverage, w, h);
  Image ref(w, h), a(w, h);
  for (size_t i = 0; i < ref.size(); ++i) ref[i] = a[i] = Rgb(0.5f);
  a.at(1, 1) = Rgb(10.5f);     // inside the mask: ignored by both masked metrics
  a.at(5, 5) = Rgb(1.5f);      // error 1 in block (4,4): mean 1/16 per channel
  for (int y = 0; y < 4; ++y)  // ±0.5 checkerboard in block (8,0): zero block mean
    for (int x = 8; x < 12; ++x) a.at(x, y) = Rgb((x + y) % 2 ? 1.0f : 0.0f);
  const ImageDiffStats s = CompareImages(a, ref, &mask);
  ASSERT_TRUE(s.masked);
  EXPECT_EQ(s.pixels_masked, 80u);
  EXPECT_EQ(s.blocks_lowfreq, 5u);
  // Squared errors: 3 (pixel (5,5)) + 16 · 3 · 0.25 (checkerboard) = 15 over 3 · 80 values.
  EXPECT_NEAR(s.rmse_masked, std::sqrt(15.0 / 240.0), 1e-12);
  // Block means: 1/16 in 3 channels of one block, 0 elsewhere; 3 · 5 values.
  EXPECT_NEAR(s.rmse_lowfreq, std::sqrt(3.0 / 256.0 / 15.0), 1e-12);
  // Means over the 80 pixels: pixel (5,5) adds 1/80, the checkerboard averages to 0.5; the
  // emitter pixel's 10.5 counts only in the whole-image mean.
  EXPECT_NEAR(s.mean_masked_a, 0.5 + 1.0 / 80.0, 1e-12);
  EXPECT_NEAR(s.mean_masked_b, 0.5, 1e-12);
  EXPECT_NEAR(s.mean_a, 0.5 + (1.0 + 10.0) / 96.0, 1e-12);
  // The whole-image RMSE still sees the emitter pixel.
  EXPECT_GT(s.rmse, s.rmse_masked);
  // Without a mask the masked metrics are absent.
  EXPECT_FALSE(CompareImages(a, ref).masked);
  // RmseOver selects pixels.
  std::vector<uint8_t> only(w * h, 0);
  only[5 * w + 5] = 1;
  EXPECT_DOUBLE_EQ(RmseOver(a, ref, only), 1.0);
}

}  // namespace
}  // namespace pf
