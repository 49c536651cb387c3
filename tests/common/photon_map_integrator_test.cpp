// The photon-map integrator's pixel radius hint (photon_map_integrator.h, pixel_radius_hint):
// each camera-path estimate first searches the ball of the previous sample's k-th distance.
// Its radiance parts (radiance_part.h) add up to the whole.
#include "common/render/photon_map_integrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"
#include "tests/common/furnace_local_pass.h"

namespace pf {
namespace {

// A shipped scene (scenes/<name>/<name>.json) on Embree with its light sampler, seen by its
// manifest camera at size × size pixels: the set-up every test below starts from.
struct ShippedScene {
  ShippedScene(const std::string& name, int size)
      : scene(LoadScene(std::filesystem::path(PF_SOURCE_DIR) / "scenes" / name / (name + ".json"))),
        accel(scene),
        lights(accel),
        camera(SquareCamera(scene, size)) {}
  static CameraSpec SquareCamera(const SceneDescription& s, int size) {
    CameraSpec spec = s.cameras.front();
    spec.width = spec.height = size;
    return spec;
  }
  SceneDescription scene;
  EmbreeScene accel;
  LightSampler lights;
  Camera camera;
};

// The hint finds the same photons, so the image equals the unhinted one up to the summation
// order of the same powers (relative 1e-5; a hint that lost or added a photon changes a pixel
// by ~1/k = 3 %), on both map structures and with the caustic map's bounded queries. The hint
// lives per pixel, so 1 and 2 threads still give the same bits.
TEST(PixelRadiusHint, SamePhotonsAsWithoutAndDeterministic) {
  const ShippedScene shipped("cornell-sphere", 32);
  const EmbreeScene& accel = shipped.accel;
  const LightSampler& lights = shipped.lights;
  const Camera& camera = shipped.camera;
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

// The separate direct map is built only when an estimator reads it (DirectMapRead): with Monte
// Carlo direct light and no local pass nothing does, so it is dropped, and the image is the one
// rendered with it present, bit for bit. PhotonDirect and the local pass still get it.
TEST(DirectMap, BuiltOnlyWhenReadAndTheImageIsTheSameWithout) {
  const ShippedScene shipped("cornell-box", 24);
  const EmbreeScene& accel = shipped.accel;
  const LightSampler& lights = shipped.lights;
  const Camera& camera = shipped.camera;
  PhotonMapIntegratorOptions io;
  io.global.k = 30;
  io.direct = DirectLightMode::kMonteCarlo;
  PhotonMapsOptions mo;
  mo.tracing.photons = 20000;
  mo.tracing.map_seed = 7;
  ConfigureMapsFor(io, &mo);
  EXPECT_TRUE(mo.separate_direct);
  EXPECT_FALSE(mo.direct_map) << "Monte Carlo direct light without a local pass reads no direct photons";
  const PhotonMaps without = PhotonMaps::Build(accel, lights, mo);
  PhotonMapsOptions with_direct = mo;
  with_direct.direct_map = true;
  const PhotonMaps with = PhotonMaps::Build(accel, lights, with_direct);
  ASSERT_FALSE(without.direct);
  ASSERT_TRUE(with.direct);
  EXPECT_GT(with.direct->size(), 0u);
  ASSERT_EQ(without.global->size(), with.global->size());
  for (size_t i = 0; i < with.global->size(); ++i)
    ASSERT_EQ(std::memcmp(&without.global->photon(i), &with.global->photon(i), sizeof(Photon)), 0) << i;
  auto render = [&](const PhotonMaps& maps) {
    const PhotonMapIntegrator integrator(accel, &lights, maps, io);
    return RenderImage(integrator, camera, RenderOptions{.spp = 2, .seed = 5, .threads = 2});
  };
  const Image a = render(without), b = render(with);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.pixels().data(), b.pixels().data(), a.size() * sizeof(Rgb)), 0);

  PhotonMapIntegratorOptions local = io;
  local.local_pass_rays = 2;
  EXPECT_TRUE(DirectMapRead(local)) << "the local pass's gather hits read the direct photons";
  PhotonMapIntegratorOptions photon_direct = io;
  photon_direct.direct = DirectLightMode::kPhotonDirect;
  EXPECT_TRUE(DirectMapRead(photon_direct));
  EXPECT_THROW(PhotonMapIntegrator(accel, &lights, without, local), InputError);
}

// radiance_part.h: the photon-map part and the emission + direct light part add up to the whole
// radiance. With the same random streams each pixel's parts sum to the kAll value up to float
// rounding (every random number is drawn by slot, so leaving one part out does not shift the
// other's numbers): a dropped or doubled term (emission seen through the glass sphere, direct light
// at a surface behind a mirror, a caustic) would show as a difference of its size. The emission +
// direct light part reads no map: with empty maps it is the same bits.
// Without the local pass: with it the parts were measured not to add up (up to 7 % at some
// pixels), so --hier-part indirect refuses the local pass (job_spec.cpp, task_executor.cpp);
// LocalPassUnmappedPartNeedsNoMap below keeps what does hold there.
TEST(RadianceParts, MappedPlusUnmappedIsTheWholeRadiance) {
  const ShippedScene shipped("cornell-sphere", 32);
  const EmbreeScene& accel = shipped.accel;
  const LightSampler& lights = shipped.lights;
  const Camera& camera = shipped.camera;
  PhotonMapIntegratorOptions io;
  io.global.k = 30;
  io.caustic = DefaultCausticOptions(30, accel.bounds());
  io.direct = DirectLightMode::kMonteCarlo;
  io.monte_carlo.shadow_rays = 4;
  PhotonMapsOptions mo;
  mo.tracing.photons = 20000;
  mo.tracing.map_seed = 3;
  mo.caustic = CausticMapMode::kOn;
  ConfigureMapsFor(io, &mo);
  const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
  ASSERT_TRUE(maps.caustic);
  ASSERT_FALSE(maps.direct) << "no local pass: no direct map is read";
  const PhotonMaps empty;
  auto render = [&](RadiancePart part, const PhotonMaps& m) {
    PhotonMapIntegratorOptions o = io;
    o.part = part;
    const PhotonMapIntegrator integrator(accel, &lights, m, o);
    return RenderImage(integrator, camera, RenderOptions{.spp = 4, .seed = 5, .threads = 2});
  };
  const Image all = render(RadiancePart::kAll, maps), mapped = render(RadiancePart::kMapped, maps),
              unmapped = render(RadiancePart::kUnmapped, maps),
              unmapped_no_map = render(RadiancePart::kUnmapped, empty);
  EXPECT_EQ(std::memcmp(unmapped.pixels().data(), unmapped_no_map.pixels().data(), all.size() * sizeof(Rgb)),
            0);
  double sum_mapped = 0, sum_unmapped = 0;
  for (size_t i = 0; i < all.size(); ++i) {
    sum_mapped += mapped[i].Mean();
    sum_unmapped += unmapped[i].Mean();
    for (int c = 0; c < 3; ++c)
      ASSERT_NEAR(mapped[i][c] + unmapped[i][c], all[i][c], 1e-5 * std::max(1e-2f, all[i][c]))
          << "pixel " << i;
  }
  EXPECT_GT(sum_mapped, 0.05 * sum_unmapped) << "both parts carry light";
  EXPECT_GT(sum_unmapped, 0.05 * sum_mapped);
}

// With the local pass (§4.3), also with the irradiance cache, the maps hold a direct map for the
// mapped part's gathers; the emission + direct light part reads none of it and renders the same
// bits with empty maps (it threw before: the integrator asked for a direct map it never reads).
TEST(RadianceParts, LocalPassUnmappedPartNeedsNoMap) {
  const ShippedScene shipped("cornell-sphere", 16);
  const EmbreeScene& accel = shipped.accel;
  const LightSampler& lights = shipped.lights;
  const Camera& camera = shipped.camera;
  for (const float cache : {0.0f, 0.3f}) {
    PhotonMapIntegratorOptions io;
    io.global.k = 30;
    io.direct = DirectLightMode::kMonteCarlo;
    io.monte_carlo.shadow_rays = 4;
    io.local_pass_rays = 2;
    io.irradiance_cache.error = cache;
    io.part = RadiancePart::kUnmapped;
    PhotonMapsOptions mo;
    mo.tracing.photons = 5000;
    mo.tracing.map_seed = 3;
    ConfigureMapsFor(io, &mo);
    const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
    ASSERT_TRUE(maps.direct) << "the local pass reads the direct map";
    const PhotonMaps empty;
    const RenderOptions ro{.spp = 2, .seed = 5, .threads = 1};
    const Image with = RenderImage(PhotonMapIntegrator(accel, &lights, maps, io), camera, ro);
    const Image without = RenderImage(PhotonMapIntegrator(accel, &lights, empty, io), camera, ro);
    EXPECT_EQ(std::memcmp(with.pixels().data(), without.pixels().data(), with.size() * sizeof(Rgb)), 0);
    double sum = 0;
    for (size_t i = 0; i < with.size(); ++i) sum += with[i].Mean();
    EXPECT_GT(sum, 0.0) << "emission and direct light";
  }
}

}  // namespace
}  // namespace pf
