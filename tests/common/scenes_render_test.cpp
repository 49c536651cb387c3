// Every scene shipped in scenes/ loads and renders: each manifest, path-traced at a
// tiny resolution, gives a finite image that is not black, with no NaN/Inf samples dropped.
#include <gtest/gtest.h>

#include <filesystem>

#include "common/accel/embree_scene.h"
#include "common/render/camera.h"
#include "common/render/light_sampler.h"
#include "common/render/path_tracer.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

std::vector<std::string> Manifests() {
  std::vector<std::string> out;
  for (const auto& dir : std::filesystem::directory_iterator(std::filesystem::path(PF_SOURCE_DIR) / "scenes"))
    if (dir.is_directory())
      for (const auto& f : std::filesystem::directory_iterator(dir.path()))
        if (f.path().extension() == ".json") out.push_back(f.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

class ShippedScene : public ::testing::TestWithParam<std::string> {};

TEST_P(ShippedScene, RendersFiniteAndNotBlack) {
  const SceneDescription scene = LoadScene(GetParam());
  ASSERT_FALSE(scene.cameras.empty()) << "every shipped manifest has a camera";
  CameraSpec cam = scene.cameras.front();
  cam.width = 24;
  cam.height = 16;
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  ASSERT_FALSE(lights.empty());
  const PathTracer tracer(accel, lights);
  RenderStats stats;
  const Image img = RenderImage(tracer, Camera(cam), RenderOptions{.spp = 8, .seed = 3}, &stats);
  double sum = 0;
  for (const Rgb& c : img.pixels()) {
    ASSERT_TRUE(c.IsFinite());
    sum += c.Mean();
  }
  EXPECT_GT(sum, 0.0);
  EXPECT_EQ(stats.nonfinite_samples, 0u);
}

INSTANTIATE_TEST_SUITE_P(Scenes, ShippedScene, ::testing::ValuesIn(Manifests()), [](const auto& info) {
  std::string name = std::filesystem::path(info.param).stem().string();
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
});

}  // namespace
}  // namespace pf
