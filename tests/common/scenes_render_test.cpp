// Every scene shipped in scenes/ loads and renders: each manifest, path-traced at a
// tiny resolution, gives a finite image that is not black, with no NaN/Inf samples dropped.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <iostream>
#include <numbers>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon_maps.h"
#include "common/render/job_render_settings.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/scene/mgf_color.h"
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

// The CONFERENCE-like scene (Wald 1999, §3.3.5: small, very bright exit signs overmodulate the
// radiance estimate around them). Its signs must be what the generator says, an emitter of
// luminance ed / (π · 179) = 100 W/(m²·sr) (mgf_loader.h), 10x the ceiling panels, and a pixel
// that sees only the sign must read exactly that radiance: with both integrators a camera ray
// that hits an emitter returns its Le (the sign reflects nothing), whatever the photons do
// around it. A wrong emission scale, a sign facing the wall, or a photon estimate added on
// emitters fails here.
TEST(ConferenceScene, ExitSignsReadTheirRadiance) {
  const SceneDescription scene =
      LoadScene(std::filesystem::path(PF_SOURCE_DIR) / "scenes/conference/conference.json");
  EXPECT_EQ(scene.num_lights, 8u) << "six ceiling panels and two exit signs";
  const Material* sign = nullptr;
  const Material* panel = nullptr;
  for (const Material& m : scene.materials) {
    if (m.name == "exit_sign") sign = &m;
    if (m.name == "panel") panel = &m;
  }
  ASSERT_NE(sign, nullptr);
  ASSERT_NE(panel, nullptr);
  // mgf_loader.h: Le = ed / (π · 179 lm/W) × the colour's RGB at luminance 1 (MGF's own §6.1.1
  // matrix, whose white is equal-energy grey: the panels' `c` gives RGB 1).
  const float scale = float(56235.0 / (std::numbers::pi * 179.0));  // 100.0
  const Rgb expected = mgf::ChromaRgb(mgf::Chroma{.x = 0.3, .y = 0.5}) * scale;
  EXPECT_NEAR(scale, 100.0f, 0.01f);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(sign->emission[c], expected[c], 1e-4f * scale);
    EXPECT_NEAR(panel->emission[c], 5622.0 / (std::numbers::pi * 179.0), 1e-4);  // 10.0
  }
  EXPECT_GT(expected.g, 2.0f * std::max(expected.r, expected.b)) << "green";

  // A camera 1.44 m in front of the sign over the left door (emitter 0.28 x 0.08 m centred at
  // y 2.85, z 1.25, facing -x at x 7.939): 10° over 32 pixels is 7.9 mm per pixel at the sign, so
  // rows 12-19 (±32 mm) see nothing but the emitter.
  CameraSpec cam;
  cam.eye = Vec3(6.5f, 2.85f, 1.25f);
  cam.look_at = Vec3(8.0f, 2.85f, 1.25f);
  cam.vfov_degrees = 10.0f;
  cam.width = cam.height = 32;
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  auto expect_sign = [&](const Image& img, const char* integrator) {
    for (int y = 12; y < 20; ++y)
      for (int x = 0; x < 32; ++x) {
        const Rgb& c = img.at(x, y);
        ASSERT_NEAR(c.r, expected.r, 1e-4f * scale) << integrator << " " << x << "," << y;
        ASSERT_NEAR(c.g, expected.g, 1e-4f * scale) << integrator << " " << x << "," << y;
        ASSERT_NEAR(c.b, expected.b, 1e-4f * scale) << integrator << " " << x << "," << y;
      }
    // Just outside the emitter (the hood and the housing) the image is far dimmer than the sign.
    EXPECT_LT(img.at(16, 0).Luminance(), 0.05f * expected.Luminance()) << integrator;
    std::cout << "[ conference ] " << integrator
              << ": pixel (16, 0), the wall between hood and ceiling: " << img.at(16, 0).Luminance() << "\n";
  };
  RenderStats stats;
  const PathTracer tracer(accel, lights);
  expect_sign(RenderImage(tracer, Camera(cam), RenderOptions{.spp = 4, .seed = 1}, &stats), "path");

  JobRenderSettings settings;
  settings.photons = 20000;
  settings.k = 50;
  settings = settings.Resolved(scene);
  PhotonMapsOptions mo = settings.MapsOptions();
  mo.tracing.map_seed = 1;
  const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
  const PhotonMapIntegrator integrator(accel, &lights, maps, settings.IntegratorOptions(accel.bounds()));
  expect_sign(RenderImage(integrator, Camera(cam), RenderOptions{.spp = 4, .seed = 1}, &stats), "photon map");
  EXPECT_EQ(stats.nonfinite_samples, 0u);
}

}  // namespace
}  // namespace pf
