// Chapter-4 estimators (Wald 1999, §4.2, §4.3): separate direct light by Monte Carlo and by
// PhotonDirect (both variants for non-contributing lights) agree with the path tracer in the
// mean; the local pass reproduces the furnace's analytic value.
#include "common/estimators/direct_light.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>

#include "common/photon/photon_maps.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "tests/common/furnace_local_pass.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::MapsFor;

using testing::AddMaterial;
using testing::AddQuad;

// A black wall at x = 0.3, z in [0.2, 1.4], both faces: it hides lights on its right (x > 0.3)
// from much of the floor's left half.
void AddBlackWall(SceneDescription& s, uint32_t black_id) {
  AddQuad(s, {0.3f, -3, 0.2f}, {0.3f, 3, 0.2f}, {0.3f, 3, 1.4f}, {0.3f, -3, 1.4f}, black_id);
  AddQuad(s, {0.3f, -3, 0.2f}, {0.3f, -3, 1.4f}, {0.3f, 3, 1.4f}, {0.3f, 3, 0.2f}, black_id);
}

// A floor lit by two small area lights of different power, one of them partly hidden behind a
// black occluder (so some floor points have a non-contributing light). Lights and occluder
// are black: the floor receives direct light only, and the path tracer's image is exactly Ld.
SceneDescription TwoLightScene() {
  SceneDescription s;
  const Material floor{.diffuse_reflectance = Rgb(0.6f)};
  Material black;
  const Material bright{.emission = Rgb(30.0f)};
  const Material dim{.emission = Rgb(8.0f, 10.0f, 12.0f)};
  const uint32_t floor_id = AddMaterial(s, floor);
  const uint32_t black_id = AddMaterial(s, black);
  AddQuad(s, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, floor_id);
  // Lights face down (clockwise seen from above).
  AddQuad(s, {-1.2f, -0.2f, 1}, {-1.2f, 0.2f, 1}, {-0.8f, 0.2f, 1}, {-0.8f, -0.2f, 1}, AddMaterial(s, bright),
          0);
  AddQuad(s, {0.8f, -0.3f, 1.5f}, {0.8f, 0.3f, 1.5f}, {1.4f, 0.3f, 1.5f}, {1.4f, -0.3f, 1.5f},
          AddMaterial(s, dim), 1);
  AddBlackWall(s, black_id);  // between the dim light and the left half of the floor
  s.num_lights = 2;
  return s;
}

CameraSpec FloorCamera() {
  return testing::LookAtCamera(Vec3(0, -0.5f, 4.0f), Vec3(0, 0, 0), Vec3(0, 1, 0), 50, 24, 16);
}

constexpr int kRuns = 8;       // independent seeds per estimate of a mean
constexpr uint32_t kSpp = 64;  // photon-map images; the path tracer's get 4x

// The floor camera's path-traced image: exactly Ld where lights and occluders are black.
Image PathImage(const EmbreeScene& accel, const LightSampler& lights, uint64_t seed) {
  return RenderImage(PathTracer(accel, lights), Camera(FloorCamera()),
                     RenderOptions{.spp = kSpp * 4, .seed = seed});
}

// The floor camera's image with photon maps of 20000 photons built for `io`, seeded by `seed`.
Image PhotonMapImage(const EmbreeScene& accel, const LightSampler& lights,
                     const PhotonMapIntegratorOptions& io, uint64_t seed) {
  const PhotonMaps maps = MapsFor(accel, lights, io, 20000, seed);
  EXPECT_EQ(maps.global->size(), 0u) << "no indirect light in this scene";
  const PhotonMapIntegrator integrator(accel, &lights, maps, io);
  return RenderImage(integrator, Camera(FloorCamera()), RenderOptions{.spp = kSpp, .seed = seed});
}

struct MeanAndError {
  double mean = 0, standard_error = 0;
};

// Mean of `values` with the standard error from their spread.
MeanAndError Summarize(const std::vector<double>& values) {
  const double n = double(values.size());
  MeanAndError out;
  for (double v : values) out.mean += v / n;
  double var = 0;
  for (double v : values) var += (v - out.mean) * (v - out.mean) / (n - 1);
  out.standard_error = std::sqrt(var / n);
  return out;
}

// Mean over the image columns [x0, x1).
double ColumnsMean(const Image& img, int x0, int x1) {
  double m = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = x0; x < x1; ++x) m += img.at(x, y).Mean();
  return m / double(img.height() * (x1 - x0));
}

// Image mean over `runs` independent seeds; the standard error from the spread of the runs.
template <typename MakeImage>
MeanAndError RunMeans(int runs, MakeImage&& make) {
  std::vector<double> means;
  for (int r = 0; r < runs; ++r) {
    const Image img = make(uint64_t(1000 + r));
    means.push_back(ColumnsMean(img, 0, img.width()));
  }
  return Summarize(means);
}

// The same for the left and the right half of the image separately.
template <typename MakeImage>
std::array<MeanAndError, 2> RunHalfMeans(int runs, MakeImage&& make) {
  std::vector<double> left, right;
  for (int r = 0; r < runs; ++r) {
    const Image img = make(uint64_t(2000 + r));
    left.push_back(ColumnsMean(img, 0, img.width() / 2));
    right.push_back(ColumnsMean(img, img.width() / 2, img.width()));
  }
  return {Summarize(left), Summarize(right)};
}

TEST(DirectLight, MonteCarloAndBothPhotonDirectVariantsAgreeWithThePathTracer) {
  const SceneDescription scene = TwoLightScene();
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 2u);
  const MeanAndError reference =
      RunMeans(kRuns, [&](uint64_t seed) { return PathImage(accel, lights, seed); });

  auto photon_map_run = [&](DirectLightMode mode, NonContributingMode nc) {
    PhotonMapIntegratorOptions io;
    io.direct = mode;
    io.monte_carlo.shadow_rays = 4;
    io.photon_direct.samples = 4;
    io.photon_direct.k = 20;
    io.photon_direct.non_contributing = nc;
    return RunMeans(kRuns, [&](uint64_t seed) { return PhotonMapImage(accel, lights, io, seed); });
  };
  const MeanAndError mc = photon_map_run(DirectLightMode::kMonteCarlo, NonContributingMode::kOneRandom);
  const MeanAndError pd_random =
      photon_map_run(DirectLightMode::kPhotonDirect, NonContributingMode::kOneRandom);
  const MeanAndError pd_each = photon_map_run(DirectLightMode::kPhotonDirect, NonContributingMode::kEachOne);

  for (const auto& [name, m] : {std::pair{"monte carlo", mc},
                                {"photon direct, one random", pd_random},
                                {"photon direct, each one", pd_each}}) {
    const double bound = 3.5 * std::sqrt(m.standard_error * m.standard_error +
                                         reference.standard_error * reference.standard_error);
    EXPECT_NEAR(m.mean, reference.mean, bound)
        << name << " (path tracer " << reference.mean << " ± " << reference.standard_error << ", " << name
        << " ± " << m.standard_error << ")";
    // The bound must be tight enough to mean something: < 1.5 % of the mean.
    EXPECT_LT(bound, 0.015 * reference.mean) << name;
  }
}

// PhotonDirect's handling of the non-contributing lights, exercised: four lights and only k = 3
// direct photons per query, so at most points two or three lights are non-contributing yet
// visible. One-random sends one ray to one of them weighted by their number, each-one one ray
// to every one of them; both must match the path tracer on each half of the image (a wrong
// weight, or dropping those samples, is 10 %+ off on the right half, where the dim lights are).
TEST(DirectLight, PhotonDirectNonContributingLightsAreWeightedRightWithFourLights) {
  SceneDescription s;
  const Material floor{.diffuse_reflectance = Rgb(0.6f)};
  const uint32_t floor_id = AddMaterial(s, floor);
  const uint32_t black_id = AddMaterial(s, Material{});
  AddQuad(s, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, floor_id);
  const auto light = [&](float x, float y, float z, float half, Rgb le, uint32_t id) {
    const Material m{.emission = le};
    AddQuad(s, {x - half, y - half, z}, {x - half, y + half, z}, {x + half, y + half, z},
            {x + half, y - half, z}, AddMaterial(s, m), id);
  };
  light(-1.0f, 0.0f, 1.0f, 0.2f, Rgb(30.0f), 0);
  light(1.1f, -0.9f, 1.3f, 0.25f, Rgb(10.0f, 8.0f, 6.0f), 1);
  light(1.1f, 0.9f, 1.3f, 0.25f, Rgb(6.0f, 8.0f, 10.0f), 2);
  light(1.6f, 0.0f, 0.9f, 0.15f, Rgb(12.0f), 3);
  AddBlackWall(s, black_id);
  s.num_lights = 4;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 4u);
  const auto reference = RunHalfMeans(kRuns, [&](uint64_t seed) { return PathImage(accel, lights, seed); });
  for (NonContributingMode nc : {NonContributingMode::kOneRandom, NonContributingMode::kEachOne}) {
    PhotonMapIntegratorOptions io;
    io.direct = DirectLightMode::kPhotonDirect;
    io.photon_direct.samples = 4;
    io.photon_direct.k = 3;
    io.photon_direct.non_contributing = nc;
    const auto halves =
        RunHalfMeans(kRuns, [&](uint64_t seed) { return PhotonMapImage(accel, lights, io, seed); });
    for (int h = 0; h < 2; ++h) {
      const MeanAndError& m = halves[h];
      const MeanAndError& ref = reference[h];
      const double bound = 3.5 * std::hypot(m.standard_error, ref.standard_error);
      EXPECT_NEAR(m.mean, ref.mean, bound)
          << (h ? "right" : "left") << " half, mode " << int(nc) << " (path tracer " << ref.mean << ")";
      EXPECT_LT(bound, 0.03 * ref.mean) << (h ? "right" : "left") << " half, mode " << int(nc);
    }
  }
}

// §4.3 in the furnace: final gathering from the photon-map estimate must give Le/(1−a).
TEST(LocalPass, FurnaceAnalyticValueWithinOnePercent) {
  testing::ExpectFurnaceLocalPassWithinOnePercent(LocalPassLookup::kFull, 0);
}

// The local pass at a surface whose glossy lobe is estimated from the maps (glossy depth 0):
// caustic light must reach the glossy lobe once (from the maps' glossy estimate), not also from
// the caustic estimate of the gathering point. The floor is lit only through a mirror ceiling
// (an up-facing light under it), so every photon on it is a caustic photon and every gather ray
// ends on the mirror, which adds nothing (that light is in the caustic map): with and without
// the local pass the images must agree. The glossy caustic counted twice was 70 % above.
TEST(LocalPass, GlossyCausticsAreCountedOnce) {
  SceneDescription s;
  const Material floor{
      .diffuse_reflectance = Rgb(0.3f), .specular_reflectance = Rgb(0.5f), .specular_roughness = 0.1f};
  const Material mirror{.specular_reflectance = Rgb(0.9f)};
  const Material light{.emission = Rgb(20.0f)};
  AddQuad(s, {-3, -3, 0}, {3, -3, 0}, {3, 3, 0}, {-3, 3, 0}, AddMaterial(s, floor));
  AddQuad(s, {-3, -3, 2}, {-3, 3, 2}, {3, 3, 2}, {3, -3, 2}, AddMaterial(s, mirror));  // faces down
  AddQuad(s, {-0.3f, -0.3f, 0.8f}, {0.3f, -0.3f, 0.8f}, {0.3f, 0.3f, 0.8f}, {-0.3f, 0.3f, 0.8f},
          AddMaterial(s, light), 0);  // faces up
  s.num_lights = 1;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  CameraSpec cam;
  // The mirror path light -> ceiling -> floor -> eye reflects at y = -1.45: the glossy
  // highlight of the caustic is in the middle of the view.
  cam.eye = Vec3(0.0f, -2.0f, 1.2f);
  cam.look_at = Vec3(0.0f, -1.3f, 0.0f);
  cam.up = Vec3(0, 0, 1);
  cam.vfov_degrees = 50;
  cam.width = 24;
  cam.height = 16;
  auto image_mean = [&](int local_pass_rays) {
    PhotonMapIntegratorOptions io;
    io.glossy_depth = 0;
    io.local_pass_rays = local_pass_rays;
    io.global.k = io.caustic.k = 100;
    io.caustic.max_radius = 0.2f;
    io.direct_photons = io.global;
    const PhotonMaps maps = MapsFor(accel, lights, io, 200000, 9);
    EXPECT_TRUE(maps.caustic && maps.caustic->size() > 10000u) << "the floor's light is a caustic";
    const PhotonMapIntegrator integrator(accel, &lights, maps, io);
    const Image img = RenderImage(integrator, Camera(cam), RenderOptions{.spp = 16, .seed = 3});
    return ColumnsMean(img, 0, img.width());
  };
  const double without = image_mean(0), with = image_mean(16);
  std::printf("image mean: maps' estimate %.5f, local pass %.5f\n", without, with);
  EXPECT_NEAR(with, without, 0.03 * without) << "local pass " << with << " vs the maps' estimate " << without;
}

// Occlusion testing (§4.1.1) removes light that bleeds through a wall: a photon-lit floor
// next to a dark room behind a thin wall.
TEST(OcclusionTest, RemovesEnergyBleedingThroughAWall) {
  SceneDescription s;
  const Material floor{.diffuse_reflectance = Rgb(0.5f)};
  const Material light{.emission = Rgb(50.0f)};
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
    const EstimateContext context{
        maps.global_attributes.origin.empty() ? nullptr : &maps.global_attributes.origin, &accel};
    return EstimateRadiance(*maps.global, bsdf, Vec3(x, 0, 0), Vec3(0, 0, 1), kLobeDiffuseReflection,
                            io.global, nearest, context)
        .radiance.Mean();
  };
  const float lit = estimate_at(0.05f, false);
  const float open_floor = estimate_at(1.0f, false), open_floor_tested = estimate_at(1.0f, true);
  const float bleeding = estimate_at(-0.01f, false);
  const float tested = estimate_at(-0.01f, true);
  const float far_dark = estimate_at(-1.0f, false);
  std::printf("lit %.4f, behind the wall: %.4f without / %.4f with the occlusion test, far side %.4f\n", lit,
              bleeding, tested, far_dark);
  EXPECT_GT(bleeding, 0.25f * lit) << "without the test, light from the lit side bleeds through";
  EXPECT_GT(bleeding, 4.0f * far_dark);
  EXPECT_LT(tested, 0.05f * bleeding) << "with it, the dark side is (almost) dark";
  EXPECT_LE(tested, 2.0f * far_dark) << "no darker-than-dark artefact either: at most the far side's level";
  // Where every photon's origin is in plain sight, the test must drop nothing (self-occlusion
  // at the ray's ends would darken here).
  EXPECT_NEAR(open_floor_tested, open_floor, 0.01f * open_floor) << "open floor, lit side";
}

// The occlusion test's two failure modes on the rooms scenes are built: a floor lit on one side of
// a dividing wall of no thickness (one polygon, as MGF and OBJ rooms have it), and the dark side
// lit only through a slit in it. Radius queries of 0.03 (a progressive pass's disk), 400k photons.
struct DividedFloor {
  SceneDescription scene;
  uint32_t floor_id = 0;
  explicit DividedFloor(bool slit) {
    floor_id = AddMaterial(scene, Material{.diffuse_reflectance = Rgb(0.5f)});
    AddQuad(scene, {-2, -1, 0}, {2, -1, 0}, {2, 1, 0}, {-2, 1, 0}, floor_id);
    if (slit) {  // two pieces with a 2 cm slit at |y| < 0.01
      AddQuad(scene, {0, -1, 0}, {0, -0.01f, 0}, {0, -0.01f, 2}, {0, -1, 2}, floor_id);
      AddQuad(scene, {0, 0.01f, 0}, {0, 1, 0}, {0, 1, 2}, {0, 0.01f, 2}, floor_id);
    } else {
      AddQuad(scene, {0, -1, 0}, {0, 1, 0}, {0, 1, 2}, {0, -1, 2}, floor_id);  // faces +x
    }
    const uint32_t light = AddMaterial(scene, Material{.emission = Rgb(50.0f)});
    AddQuad(scene, {1.4f, -0.1f, 1}, {1.4f, 0.1f, 1}, {1.6f, 0.1f, 1}, {1.6f, -0.1f, 1}, light,
            0);  // faces down
    scene.num_lights = 1;
  }
};

float FloorEstimate(const EmbreeScene& accel, const PhotonMaps& maps, const Material& floor, const Vec3& x,
                    bool occlusion) {
  RadianceEstimateOptions o;
  o.radius_query = true;
  o.max_radius = 0.03f;
  o.occlusion_test = occlusion;
  const Bsdf bsdf(floor, Vec3(0, 0, 1), Vec3(0, 0, 1));
  NearestPhotons nearest;
  const EstimateContext context{&maps.global_attributes.origin, &accel};
  return EstimateRadiance(*maps.global, bsdf, x, Vec3(0, 0, 1), kLobeDiffuseReflection, o, nearest, context)
      .radiance.Mean();
}

PhotonMaps DividedFloorMaps(const EmbreeScene& accel, const LightSampler& lights) {
  PhotonMapIntegratorOptions io;
  io.global.occlusion_test = true;  // keeps the origins
  PhotonMapsOptions mo;
  mo.tracing.photons = 400000;
  ConfigureMapsFor(io, &mo);
  return PhotonMaps::Build(accel, lights, mo);
}

// Where the wall meets the floor: photons on the lit side that left the wall's lit face must not
// light the dark side's floor within a disk of the wall. The origins are stored off the wall on
// its lit side, so the test ray from the dark side crosses the wall whatever its angle (a ray
// shortened by an offset of its own stopped short of the wall at grazing angles: bright seams).
TEST(OcclusionTest, AWallWithoutThicknessKeepsTheSeamDark) {
  const DividedFloor rooms(false);
  const EmbreeScene accel(rooms.scene);
  const LightSampler lights(accel);
  const PhotonMaps maps = DividedFloorMaps(accel, lights);
  ASSERT_FALSE(maps.global_attributes.origin.empty());
  const Material& floor = rooms.scene.materials[rooms.floor_id];
  double seam = 0, seam_untested = 0, lit = 0, lit_untested = 0;
  for (int i = 0; i < 40; ++i) {
    const float y = -0.8f + 0.04f * float(i);
    seam += FloorEstimate(accel, maps, floor, Vec3(-0.004f, y, 0), true);
    seam_untested += FloorEstimate(accel, maps, floor, Vec3(-0.004f, y, 0), false);
    lit += FloorEstimate(accel, maps, floor, Vec3(0.05f, y, 0), true);
    lit_untested += FloorEstimate(accel, maps, floor, Vec3(0.05f, y, 0), false);
  }
  std::printf("along the seam: %.5f with the test, %.5f without; lit side %.5f with, %.5f without\n",
              seam / 40, seam_untested / 40, lit / 40, lit_untested / 40);
  EXPECT_GT(seam_untested, 0.3 * lit) << "without the test the lit side bleeds through";
  // Nothing lights the dark side here (no ceiling to reflect over the wall): exactly dark.
  EXPECT_EQ(seam, 0.0) << "with the test the seam is as dark as the dark side";
  // Next to the wall on the lit side many photons came off the wall within the reach: the ray
  // ends at their origin, off the wall on this side, and must not hit the wall there.
  EXPECT_NEAR(lit, lit_untested, 0.01 * lit_untested) << "nothing dropped on the lit side";
}

// The dark side lit only through a 2 cm slit: the photons in the beam on its floor came straight
// from the light, through the slit. A ray from a point beside the photon to the light misses the
// slit, though the photon is right there; the test looks back along the photon's path only as far
// as kOcclusionReach search radii, so it keeps them: the estimate with the test is the one without
// (there is no wall within a disk of x to bleed through).
TEST(OcclusionTest, KeepsLightThatCameThroughANarrowOpening) {
  const DividedFloor rooms(true);
  const EmbreeScene accel(rooms.scene);
  const LightSampler lights(accel);
  const PhotonMaps maps = DividedFloorMaps(accel, lights);
  const Material& floor = rooms.scene.materials[rooms.floor_id];
  // The slit runs from floor to top, so the light's beam through it is a thin sheet at y ≈ 0 that
  // lands along the whole dark floor; nothing else lights the dark side (the wall has no ceiling
  // to reflect over it).
  double tested = 0, untested = 0;
  for (int i = 0; i < 20; ++i) {
    const Vec3 x(-0.8f - 0.015f * float(i), 0.0f, 0.0f);
    tested += FloorEstimate(accel, maps, floor, x, true);
    untested += FloorEstimate(accel, maps, floor, x, false);
  }
  std::printf("in the beam through the slit: %.5f with the test, %.5f without\n", tested / 20, untested / 20);
  ASSERT_GT(untested, 0.0);
  EXPECT_NEAR(tested, untested, 0.03 * untested);
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
  while (disk.size() < 400 || half.size() < 200) {  // both sets large enough for what follows
    const Vec3 p(2 * rng.Uniform() - 1, 2 * rng.Uniform() - 1, 0);
    if (LengthSquared(p) >= 1) continue;
    disk.push_back(p);
    if (p.x >= 0) half.push_back(p);
  }
  auto by_distance = [](std::vector<Vec3> v) {
    std::sort(v.begin(), v.end(),
              [](const Vec3& a, const Vec3& b) { return LengthSquared(a) < LengthSquared(b); });
    return v;
  };
  ASSERT_GE(half.size(), 200u);
  const auto d = by_distance(disk), h = by_distance(std::vector<Vec3>(half.begin(), half.begin() + 200));
  EXPECT_EQ(AdaptiveK(Vec3(0.0f), d, 20), int(d.size()));
  EXPECT_LE(AdaptiveK(Vec3(0.0f), h, 20), 40) << "a half disk is (close to) the border case";
  EXPECT_EQ(AdaptiveK(Vec3(0.0f), h, 0), 200) << "k_min = 0 switches adaptive k off";
}

}  // namespace
}  // namespace pf
