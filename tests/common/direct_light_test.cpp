// Chapter-4 estimators (Wald 1999, §4.2, §4.3): separate direct light by Monte Carlo and by
// PhotonDirect (both variants for non-contributing lights) agree with the path tracer in the
// mean; the local pass reproduces the furnace's analytic value.
#include "common/estimators/direct_light.h"

#include <gtest/gtest.h>

#include <cmath>

#include "common/photon/photon_maps.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;
using testing::AddSphere;

// A floor lit by two small area lights of different power, one of them partly hidden behind a
// black occluder (so some floor points have a non-contributing light). Lights and occluder
// are black: the floor receives direct light only, and the path tracer's image is exactly Ld.
SceneDescription TwoLightScene() {
  SceneDescription s;
  Material floor;
  floor.diffuse_reflectance = Rgb(0.6f);
  Material black;
  Material bright;
  bright.emission = Rgb(30.0f);
  Material dim;
  dim.emission = Rgb(8.0f, 10.0f, 12.0f);
  const uint32_t floor_id = AddMaterial(s, floor);
  const uint32_t black_id = AddMaterial(s, black);
  AddQuad(s, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, floor_id);
  // Lights face down (clockwise seen from above).
  AddQuad(s, {-1.2f, -0.2f, 1}, {-1.2f, 0.2f, 1}, {-0.8f, 0.2f, 1}, {-0.8f, -0.2f, 1}, AddMaterial(s, bright), 0);
  AddQuad(s, {0.8f, -0.3f, 1.5f}, {0.8f, 0.3f, 1.5f}, {1.4f, 0.3f, 1.5f}, {1.4f, -0.3f, 1.5f}, AddMaterial(s, dim), 1);
  // A black wall at x = 0.3 between the dim light and the left half of the floor (both faces).
  AddQuad(s, {0.3f, -3, 0.2f}, {0.3f, 3, 0.2f}, {0.3f, 3, 1.4f}, {0.3f, -3, 1.4f}, black_id);
  AddQuad(s, {0.3f, -3, 0.2f}, {0.3f, -3, 1.4f}, {0.3f, 3, 1.4f}, {0.3f, 3, 0.2f}, black_id);
  s.num_lights = 2;
  return s;
}

CameraSpec FloorCamera() {
  CameraSpec c;
  c.eye = Vec3(0, -0.5f, 4.0f);
  c.look_at = Vec3(0, 0, 0);
  c.up = Vec3(0, 1, 0);
  c.vfov_degrees = 50;
  c.width = 24;
  c.height = 16;
  return c;
}

struct MeanAndError {
  double mean = 0, standard_error = 0;
};

// Image mean over `runs` independent seeds; the standard error from the spread of the runs.
template <typename MakeImage>
MeanAndError RunMeans(int runs, MakeImage&& make) {
  std::vector<double> means;
  for (int r = 0; r < runs; ++r) {
    const Image img = make(uint64_t(1000 + r));
    double m = 0;
    for (const Rgb& c : img.pixels()) m += c.Mean();
    means.push_back(m / double(img.size()));
  }
  MeanAndError out;
  for (double m : means) out.mean += m / runs;
  double var = 0;
  for (double m : means) var += (m - out.mean) * (m - out.mean) / (runs - 1);
  out.standard_error = std::sqrt(var / runs);
  return out;
}

TEST(DirectLight, MonteCarloAndBothPhotonDirectVariantsAgreeWithThePathTracer) {
  const SceneDescription scene = TwoLightScene();
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 2u);
  const Camera camera(FloorCamera());
  constexpr int kRuns = 8;
  const uint32_t spp = 64;

  const PathTracer path(accel, lights);
  const MeanAndError reference = RunMeans(kRuns, [&](uint64_t seed) {
    return RenderImage(path, camera, RenderOptions{.spp = spp * 4, .seed = seed});
  });

  auto photon_map_run = [&](DirectLightMode mode, NonContributingMode nc) {
    PhotonMapIntegratorOptions io;
    io.direct = mode;
    io.monte_carlo.shadow_rays = 4;
    io.photon_direct.samples = 4;
    io.photon_direct.k = 20;
    io.photon_direct.non_contributing = nc;
    PhotonMapsOptions mo;
    mo.tracing.photons = 20000;
    ConfigureMapsFor(io, &mo);
    return RunMeans(kRuns, [&](uint64_t seed) {
      mo.tracing.map_seed = seed;
      const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
      EXPECT_EQ(maps.global->size(), 0u) << "no indirect light in this scene";
      const PhotonMapIntegrator integrator(accel, &lights, maps, io);
      return RenderImage(integrator, camera, RenderOptions{.spp = spp, .seed = seed});
    });
  };
  const MeanAndError mc = photon_map_run(DirectLightMode::kMonteCarlo, NonContributingMode::kOneRandom);
  const MeanAndError pd_random = photon_map_run(DirectLightMode::kPhotonDirect, NonContributingMode::kOneRandom);
  const MeanAndError pd_each = photon_map_run(DirectLightMode::kPhotonDirect, NonContributingMode::kEachOne);

  for (const auto& [name, m] : {std::pair{"monte carlo", mc}, {"photon direct, one random", pd_random},
                                {"photon direct, each one", pd_each}}) {
    const double bound = 3.5 * std::sqrt(m.standard_error * m.standard_error +
                                         reference.standard_error * reference.standard_error);
    EXPECT_NEAR(m.mean, reference.mean, bound) << name << " (path tracer " << reference.mean << " ± "
                                               << reference.standard_error << ", " << name << " ± "
                                               << m.standard_error << ")";
    // The bound must be tight enough to mean something: < 1.5 % of the mean.
    EXPECT_LT(bound, 0.015 * reference.mean) << name;
  }
}

// §4.3 in the furnace: final gathering from the photon-map estimate must give Le/(1−a).
TEST(LocalPass, FurnaceAnalyticValueWithinOnePercent) {
  SceneDescription s;
  Material wall;
  wall.diffuse_reflectance = Rgb(0.8f);
  wall.emission = Rgb(1.0f);
  AddSphere(s, Vec3(0.0f), 1.0f, 5, AddMaterial(s, wall), true, 0, false);
  s.num_lights = 1;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  for (DirectLightMode mode : {DirectLightMode::kNone, DirectLightMode::kMonteCarlo}) {
    PhotonMapIntegratorOptions io;
    io.global.k = 50;
    io.local_pass_rays = 16;
    io.direct = mode;
    io.direct_photons = io.global;
    PhotonMapsOptions mo;
    mo.tracing.photons = 200000;
    mo.tracing.map_seed = 4;
    ConfigureMapsFor(io, &mo);
    const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
    const PhotonMapIntegrator integrator(accel, &lights, maps, io);
    CameraSpec cam;
    cam.eye = Vec3(0.0f);
    cam.look_at = Vec3(0, 0, -1);
    cam.width = cam.height = 4;
    cam.vfov_degrees = 90;
    const Image img = RenderImage(integrator, Camera(cam), RenderOptions{.spp = 64, .seed = 2});
    for (size_t i = 0; i < img.size(); ++i)
      ASSERT_NEAR(img[i].Mean(), 5.0f, 0.05f) << "pixel " << i << " direct mode " << int(mode);
  }
}

// Occlusion testing (§4.1.1) removes light that bleeds through a wall: a photon-lit floor
// next to a dark room behind a thin wall.
TEST(OcclusionTest, RemovesEnergyBleedingThroughAWall) {
  SceneDescription s;
  Material floor;
  floor.diffuse_reflectance = Rgb(0.5f);
  Material light;
  light.emission = Rgb(50.0f);
  const uint32_t floor_id = AddMaterial(s, floor);
  AddQuad(s, {-2, -1, 0}, {2, -1, 0}, {2, 1, 0}, {-2, 1, 0}, floor_id);
  // Thin wall at x = 0 (two faces), floor to ceiling; the light is on the x > 0 side.
  AddQuad(s, {0, -1, 0}, {0, 1, 0}, {0, 1, 2}, {0, -1, 2}, floor_id);
  AddQuad(s, {0, -1, 0}, {0, -1, 2}, {0, 1, 2}, {0, 1, 0}, floor_id);
  AddQuad(s, {1.4f, -0.1f, 1}, {1.4f, 0.1f, 1}, {1.6f, 0.1f, 1}, {1.6f, -0.1f, 1}, AddMaterial(s, light), 0);
  s.num_lights = 1;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  // Estimates on the dark side: right behind the wall (x = −0.01), where a k-NN disk reaches
  // across it, and far from it (x = −1), where it does not. Light reaches the dark side only
  // indirectly, over the top of the wall.
  auto estimate_at = [&](float x, bool occlusion) {
    PhotonMapIntegratorOptions io;
    io.global.k = 200;
    io.global.occlusion_test = occlusion;
    PhotonMapsOptions mo;
    mo.tracing.photons = 100000;
    ConfigureMapsFor(io, &mo);
    const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
    const Bsdf bsdf(s.materials[floor_id], Vec3(0, 0, 1), Vec3(0, 0, 1));
    NearestPhotons nearest;
    const EstimateContext context{maps.global_attributes.origin.empty() ? nullptr : &maps.global_attributes.origin,
                                  &accel};
    return EstimateRadiance(*maps.global, bsdf, Vec3(x, 0, 0), Vec3(0, 0, 1), kLobeDiffuseReflection,
                            io.global, nearest, context)
        .radiance.Mean();
  };
  const float lit = estimate_at(0.05f, false);
  const float bleeding = estimate_at(-0.01f, false);
  const float tested = estimate_at(-0.01f, true);
  const float far_dark = estimate_at(-1.0f, false);
  std::printf("lit %.4f, behind the wall: %.4f without / %.4f with the occlusion test, far side %.4f\n", lit,
              bleeding, tested, far_dark);
  EXPECT_GT(bleeding, 0.25f * lit) << "without the test, light from the lit side bleeds through";
  EXPECT_GT(bleeding, 4.0f * far_dark);
  EXPECT_LT(tested, 0.05f * bleeding) << "with it, the dark side is (almost) dark";
  EXPECT_LE(tested, 2.0f * far_dark) << "no darker-than-dark artefact either: at most the far side's level";
}

}  // namespace
}  // namespace pf

namespace pf {
namespace {

// §4.8: the centre-of-gravity rule keeps all k photons in the interior of a uniform region and
// drops to k_min on a straight border (x on the edge of a half disk of photons).
TEST(AdaptiveK, FullDiskKeepsKHalfDiskDropsToKMin) {
  Rng rng(5, 5);
  std::vector<Vec3> disk, half;
  while (disk.size() < 400) {
    const Vec3 p(2 * rng.Uniform() - 1, 2 * rng.Uniform() - 1, 0);
    if (LengthSquared(p) >= 1) continue;
    disk.push_back(p);
    if (p.x >= 0) half.push_back(p);
  }
  auto by_distance = [](std::vector<Vec3> v) {
    std::sort(v.begin(), v.end(), [](const Vec3& a, const Vec3& b) { return LengthSquared(a) < LengthSquared(b); });
    return v;
  };
  const auto d = by_distance(disk), h = by_distance(std::vector<Vec3>(half.begin(), half.begin() + 200));
  EXPECT_EQ(AdaptiveK(Vec3(0.0f), d, 20), 400);
  EXPECT_LE(AdaptiveK(Vec3(0.0f), h, 20), 40) << "a half disk is (close to) the border case";
  EXPECT_EQ(AdaptiveK(Vec3(0.0f), h, 0), 200) << "k_min = 0 switches adaptive k off";
}

}  // namespace
}  // namespace pf
