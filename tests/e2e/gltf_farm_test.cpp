// glTF 2.0 scenes end to end (docs/gltf.md): `pf render scene.gltf` with the file's camera, its
// KHR_lights_punctual spot and emissive panel, locally and on a farm of two workers (the .gltf
// and its external .bin travel in the scene bundle), bit-identically, with both integrators.
#include <filesystem>
#include <fstream>

#include "tests/e2e/harness.h"

namespace pf::e2e {
namespace {

std::string GltfRoom() {
  return (std::filesystem::path(Binaries::Scene()).parent_path().parent_path() / "gltf-room" /
          "gltf-room.gltf")
      .string();
}

TEST(GltfFarmTest, InfoShowsTheFilesCameraAndLights) {
  TestDir dir;
  const RunResult r = RunCommand({Binaries::Pf(), "info", GltfRoom()}, dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The camera of tools/gen_gltf_room.py: yfov 0.7 rad = 40.107°, aspectRatio 1.25 → 640 × 512.
  EXPECT_NE(r.out.find("camera      Camera: eye 0,1.6,6.2 "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("res 640x512"), std::string::npos) << r.out;
  // The emissive panel (one light) and the spot.
  EXPECT_NE(r.out.find("emitting    2 triangles in 2 lights"), std::string::npos) << r.out;
}

TEST(GltfFarmTest, GltfSceneRendersOnTheFarmAsLocally) {
  BecomeSubreaper();
  TestDir dir;
  for (const std::string integrator : {"photonmap", "path"}) {
    std::vector<std::string> args = {
        Binaries::Pf(), "render", GltfRoom(), "--integrator",  integrator, "--res", "40x32", "--spp", "2",
        "--seed",       "7",      "--plan",   "multiple-maps", "--no-png", "-q"};
    if (integrator == "photonmap") args = Concat(args, {"--photons", "4000", "--k", "20"});
    // `where` is "--local-only" or a two-worker farm; the image it writes.
    auto render = [&](const std::vector<std::string>& where, const std::string& name) {
      const std::string out = (dir / (integrator + "-" + name + ".exr")).string();
      const RunResult r = RunCommand(Concat(Concat(args, where), {"-o", out}), dir.path());
      EXPECT_EQ(r.exit_code, 0) << name << ": " << r.err;
      return ReadImage(out);
    };
    const Image local = render({"--local-only"}, "local");
    EXPECT_GT(PixelSum(local), 0.0) << integrator << ": the glTF scene rendered black";
    EXPECT_TRUE(BitIdentical(render({"--workers", "2", "--threads", "1"}, "farm"), local)) << integrator;
  }
  std::vector<std::string> left;
  WaitUntil([&] { return (left = LiveChildren()).empty(); }, 5);
  EXPECT_TRUE(left.empty()) << "left behind: " << ::testing::PrintToString(left);
}

// A glTF whose only light is missing is an input error (exit 3), never a black image.
TEST(GltfFarmTest, GltfWithoutLightIsAnInputError) {
  TestDir dir;
  const std::filesystem::path scene = dir / "dark.gltf";
  std::ofstream(scene) << R"({"asset":{"version":"2.0"},"scenes":[{"nodes":[]}],"scene":0})";
  const RunResult r =
      RunCommand({Binaries::Pf(), "render", scene.string(), "--res", "8x8", "-q"}, dir.path());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("the scene has no light"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace pf::e2e
