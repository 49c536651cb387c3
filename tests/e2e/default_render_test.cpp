// A render with no method flags gives a trustworthy image (docs/renderer.md, "Choosing the
// integrator"): INVISIBLEDATE, the room lit only through a door gap, where the photon map without
// a leak guard draws the next room's light through the walls (2.2x too bright, glowing seams at the
// wall's foot; Wald 1999, §3.3.4). `pf render` chooses the photon map and the occlusion test there,
// and its budget runs the consistent plan; the image's mean must be within 3 % of the path-traced
// reference and no block may glow. The same check on the photon map forced without the test shows
// that the check sees the seams.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "common/image/exr_io.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

namespace fs = std::filesystem;

constexpr int kScale = 4;  // the reference is 320x240; the renders 80x60
constexpr int kBlock = 2;  // seams are judged on 2x2-pixel block means (an 8x8 block of the reference)
// A block's excess over the reference, in reference means, that is a seam: with the occlusion test
// the worst block (noise by the door gap's bright patch) is 1.9, without it the wall's foot 11.2.
constexpr double kGlow = 4.0;

struct Judged {
  double mean_ratio = 0;
  double worst_block_excess = 0;  // max over blocks of (block − reference block) / reference mean
};

Judged Judge(const Image& image, const Image& reference) {
  const int w = image.width(), h = image.height();
  double sum = 0, ref_sum = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) sum += image.at(x, y).Luminance();
  for (const Rgb& p : reference.pixels()) ref_sum += p.Luminance();
  const double ref_mean = ref_sum / double(reference.size());
  Judged j;
  j.mean_ratio = (sum / double(image.size())) / ref_mean;
  for (int by = 0; by + kBlock <= h; by += kBlock)
    for (int bx = 0; bx + kBlock <= w; bx += kBlock) {
      double block = 0, ref = 0;
      for (int y = by; y < by + kBlock; ++y)
        for (int x = bx; x < bx + kBlock; ++x) {
          block += image.at(x, y).Luminance();
          for (int v = 0; v < kScale; ++v)
            for (int u = 0; u < kScale; ++u) ref += reference.at(x * kScale + u, y * kScale + v).Luminance();
        }
      block /= kBlock * kBlock;
      ref /= kBlock * kBlock * kScale * kScale;
      j.worst_block_excess = std::max(j.worst_block_excess, (block - ref) / ref_mean);
    }
  return j;
}

TEST(DefaultRender, InvisibleDateWithoutMethodFlagsMatchesItsReference) {
  TestDir dir;
  const fs::path scenes = fs::path(Binaries::Scene()).parent_path().parent_path();
  const fs::path scene = scenes / "invisibledate/invisibledate.json";
  const Image reference = ReadExr(scenes / "invisibledate/reference-320.exr");
  ASSERT_EQ(reference.width(), 80 * kScale);
  // A budget no test reaches with a fixed number of passes: the image does not depend on timing.
  const auto render = [&](const std::vector<std::string>& extra, const std::string& name) {
    const fs::path out = dir / name;
    const RunResult r = RunCommand(Concat({Binaries::Pf(), "render", scene.string(), "--res", "80x60",
                                           "--time-budget", "3600", "-o", out.string(), "--no-png", "-q"},
                                          extra),
                                   dir.path(), 600);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    ImageMetadata meta;
    const Image image = ReadExr(out, &meta);
    return std::pair{image, meta};
  };
  const auto [image, meta] = render({"--passes", "24"}, "default.exr");
  EXPECT_EQ(meta.at("settings.integrator"), "photonmap");
  EXPECT_EQ(meta.at("settings.occlusion-test"), "true");
  EXPECT_EQ(meta.count("auto.occlusion-test"), 1u) << "chosen, and recorded why";
  EXPECT_EQ(meta.at("plan").rfind("progressive passes=24", 0), 0u) << meta.at("plan");
  const Judged chosen = Judge(image, reference);
  EXPECT_NEAR(chosen.mean_ratio, 1.0, 0.03);
  EXPECT_LT(chosen.worst_block_excess, kGlow) << "a block glows";

  const auto [leaky, leaky_meta] =
      render({"--passes", "24", "--integrator", "photonmap", "--set", "occlusion-test=false"}, "leaky.exr");
  const Judged forced = Judge(leaky, reference);
  EXPECT_GT(forced.mean_ratio, 1.2) << "the light of the next room bleeds through the walls";
  EXPECT_GT(forced.worst_block_excess, kGlow) << "the check must see the seams";
}

}  // namespace
}  // namespace pf::e2e
