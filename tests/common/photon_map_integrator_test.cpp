// The photon-map integrator's pixel radius hint (photon_map_integrator.h, pixel_radius_hint):
// each camera-path estimate first searches the ball of the previous sample's k-th distance.
#include "common/render/photon_map_integrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include "common/render/camera.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"
#include "tests/common/furnace_local_pass.h"

namespace pf {
namespace {

// The hint finds the same photons, so the image equals the unhinted one up to the summation
// order of the same powers (relative 1e-5; a hint that lost or added a photon changes a pixel
// by ~1/k = 3 %), on both map structures and with the caustic map's bounded queries. The hint
// lives per pixel, so 1 and 2 threads still give the same bits.
TEST(PixelRadiusHint, SamePhotonsAsWithoutAndDeterministic) {
  const SceneDescription scene =
      LoadScene(std::filesystem::path(PF_SOURCE_DIR) / "scenes/cornell-sphere/cornell-sphere.json");
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  CameraSpec spec = scene.cameras.front();
  spec.width = spec.height = 32;
  const Camera camera(spec);
  for (PhotonMapKind kind : {PhotonMapKind::kKdTree, PhotonMapKind::kBucketKdTree}) {
    PhotonMapIntegratorOptions io;
    io.global.k = 30;
    io.caustic = DefaultCausticOptions(30, accel.bounds());
    PhotonMapsOptions mo;
    mo.tracing.photons = 20000;
    mo.tracing.map_seed = 3;
    mo.kind = kind;
    mo.caustic = CausticMapMode::kOn;
    ConfigureMapsFor(io, &mo);
    const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
    ASSERT_TRUE(maps.caustic);
    auto render = [&](bool hint, int threads) {
      PhotonMapIntegratorOptions o = io;
      o.pixel_radius_hint = hint;
      const PhotonMapIntegrator integrator(accel, &lights, maps, o);
      return RenderImage(integrator, camera, RenderOptions{.spp = 4, .seed = 5, .threads = threads});
    };
    const Image plain = render(false, 2), hinted = render(true, 2), hinted_one = render(true, 1);
    ASSERT_EQ(std::memcmp(hinted.pixels().data(), hinted_one.pixels().data(), hinted.size() * sizeof(Rgb)),
              0);
    double sum = 0;
    for (size_t i = 0; i < plain.size(); ++i) {
      sum += plain[i].Mean();
      EXPECT_NEAR(hinted[i].Mean(), plain[i].Mean(), 1e-5 * std::max(1e-3f, plain[i].Mean()))
          << "pixel " << i << " map kind " << int(kind);
    }
    ASSERT_GT(sum, 0.0);
  }
}

}  // namespace
}  // namespace pf
