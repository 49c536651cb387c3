// `pf preview`: an EXR's PNG with its own automatic exposure or with another image's, so that
// renders of one scene can be compared by eye (bench/estimators_rmse.py's contact sheets).
#include <algorithm>
#include <cstdlib>

#include "common/image/exr_io.h"
#include "common/image/png_io.h"
#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

Image Ramp(float scale) {
  Image image(16, 8);
  for (size_t i = 0; i < image.size(); ++i) {
    const float v = scale * 0.01f * float(i + 1);
    image[i] = Rgb(v, 0.5f * v, 0.25f * v);
  }
  return image;
}

int MaxByteDifference(const Png8Image& a, const Png8Image& b) {
  EXPECT_EQ(a.rgb.size(), b.rgb.size());
  int worst = 0;
  for (size_t i = 0; i < std::min(a.rgb.size(), b.rgb.size()); ++i)
    worst = std::max(worst, std::abs(int(a.rgb[i]) - int(b.rgb[i])));
  return worst;
}

TEST(PfPreview, ExposureOfAnotherImageMatchesItsScale) {
  TestDir dir;
  WriteExr(dir / "image.exr", Ramp(1.0f));
  WriteExr(dir / "twice.exr", Ramp(2.0f));  // its automatic exposure is exactly half the image's
  const auto preview = [&](const std::vector<std::string>& extra, const std::string& png) {
    const RunResult r = RunCommand(
        Concat({Binaries::Pf(), "preview", (dir / "image.exr").string(), "-o", (dir / png).string()}, extra),
        dir.path());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return ReadPng8(dir / png);
  };
  const Png8Image own = preview({}, "own.png");
  const Png8Image borrowed = preview({"--exposure-of", (dir / "twice.exr").string()}, "borrowed.png");
  const Png8Image darker = preview({"--exposure", "-1"}, "darker.png");
  ASSERT_EQ(own.width, 16);
  ASSERT_EQ(own.height, 8);
  // Half the scale, one stop down: the same bytes (up to one step where 2^log2(s) rounds).
  EXPECT_LE(MaxByteDifference(borrowed, darker), 1);
  EXPECT_GT(MaxByteDifference(borrowed, own), 40) << "--exposure-of must change the exposure";
  // The brightest pixel of the image's own exposure is near the top, never clipped to black.
  EXPECT_GT(*std::max_element(own.rgb.begin(), own.rgb.end()), 200);

  const RunResult missing = RunCommand(
      {Binaries::Pf(), "preview", (dir / "nope.exr").string(), "-o", (dir / "x.png").string()}, dir.path());
  EXPECT_EQ(missing.exit_code, 2) << "a missing input is a usage error";
  EXPECT_NE(missing.err.find("nope.exr"), std::string::npos) << missing.err;
}

}  // namespace
}  // namespace pf::e2e
