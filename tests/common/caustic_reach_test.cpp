// The caustic pilot behind `integrator auto` (common/render/caustic_reach.h): its numbers against
// geometry worked out by hand, and what the rule (integrator_choice.h) makes of a glass ball lit by
// a sky, a small lamp and a point light.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>

#include "common/camera/camera.h"
#include "common/render/caustic_reach.h"
#include "common/render/integrator_choice.h"
#include "common/render/pilot_lattice.h"
#include "common/render/scene_runtime.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;
using testing::LookAtCamera;

void AddPointLight(SceneDescription& scene, Vec3d position, float intensity) {
  scene.punctual_lights.push_back(PunctualLight{.kind = PunctualLight::Kind::kPoint,
                                                .name = "point",
                                                .position = position,
                                                .intensity = Rgb(intensity),
                                                .light = scene.num_lights++});
}

void AddSky(SceneDescription& scene, float radiance) {
  scene.environment.emplace();
  scene.environment->color = Rgb(radiance);
  scene.environment->light = scene.num_lights++;
}

// A point light at the centre of the cube [-1, 1]³ whose top face is a perfect mirror (reflectance
// 1) and whose other five are grey: every photon lands on a grey face, the sixth of them that
// leave towards the top (each face subtends 4π/6) after one mirror, with all their power.
TEST(CausticReach, PunctualShareIsTheMirrorFacesSolidAngle) {
  SceneDescription scene;
  const uint32_t grey = AddMaterial(scene, Material{.name = "grey", .diffuse_reflectance = Rgb(0.5f)});
  const uint32_t mirror = AddMaterial(scene, Material{.name = "mirror", .specular_reflectance = Rgb(1.0f)});
  // Front faces inward (counter-clockwise seen from inside).
  AddQuad(scene, {-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, grey);  // floor, up
  AddQuad(scene, {-1, -1, 1}, {-1, 1, 1}, {1, 1, 1}, {1, -1, 1}, mirror);    // top, down
  AddQuad(scene, {-1, -1, -1}, {-1, 1, -1}, {-1, 1, 1}, {-1, -1, 1}, grey);  // x = -1
  AddQuad(scene, {1, -1, -1}, {1, -1, 1}, {1, 1, 1}, {1, 1, -1}, grey);      // x = 1
  AddQuad(scene, {-1, -1, -1}, {-1, -1, 1}, {1, -1, 1}, {1, -1, -1}, grey);  // y = -1
  AddQuad(scene, {-1, 1, -1}, {1, 1, -1}, {1, 1, 1}, {-1, 1, 1}, grey);      // y = 1
  AddPointLight(scene, {0, 0, 0}, 1.0f);
  const SceneRuntime runtime(scene);
  const Camera camera(LookAtCamera({0, 0, 0.5f}, {0, 0, -1}, {0, 1, 0}, 90.0f, 32, 32));
  const CausticReach reach = MeasureCausticReach(runtime, camera);
  // 2^16 photons: a binomial share's standard deviation is 0.0015.
  EXPECT_NEAR(reach.punctual_caustic_share, 1.0 / 6.0, 0.01);
  EXPECT_EQ(reach.points, 32 * 32) << "the grey floor, seen directly";
  // Looking up at the mirror: every camera ray reaches the grey floor through it.
  const Camera up(LookAtCamera({0, 0, -0.5f}, {0, 0, 1}, {0, 1, 0}, 90.0f, 32, 32));
  EXPECT_EQ(MeasureCausticReach(runtime, up).points, 32 * 32) << "the floor, seen in the mirror";

  // The top grey, and a floor of ρd = 0.5 with a smooth mirror lobe ρs = 0.3 beside it (MGF rd
  // with rs and no roughness): every photon lands once on a grey face or the floor's diffuse lobe,
  // and the floor's sixth goes on by its mirror lobe with 0.3 of its power to land again, as a caustic.
  scene.materials[mirror] = Material{.name = "grey too", .diffuse_reflectance = Rgb(0.5f)};
  const uint32_t polished = AddMaterial(
      scene,
      Material{.name = "polished", .diffuse_reflectance = Rgb(0.5f), .specular_reflectance = Rgb(0.3f)});
  scene.triangle_material[0] = scene.triangle_material[1] = polished;  // the floor's two triangles
  const double caustic = 0.3 / 6.0;
  EXPECT_NEAR(MeasureCausticReach(SceneRuntime(scene), camera).punctual_caustic_share,
              caustic / (1.0 + caustic), 0.004);

  scene.triangle_material[0] = scene.triangle_material[1] = grey;
  EXPECT_EQ(MeasureCausticReach(SceneRuntime(scene), camera).punctual_caustic_share, 0.0) << "no mirror";
}

// The fraction of a cosine-distributed ray's directions from the floor point (x, y, 0) that meet
// the wall x = 0, |y| < 10, 0 < z < 10: midpoints of a 256 × 256 grid over the cosine mapping.
double WallFraction(double x, double y) {
  constexpr int kN = 256;
  int hits = 0;
  for (int i = 0; i < kN; ++i)
    for (int j = 0; j < kN; ++j) {
      const double u1 = (i + 0.5) / kN, u2 = (j + 0.5) / kN;
      const double r = std::sqrt(u1), phi = 2.0 * std::numbers::pi * u2;
      const double dx = r * std::cos(phi), dy = r * std::sin(phi), dz = std::sqrt(1.0 - u1);
      if (dx >= 0.0) continue;
      const double t = -x / dx;
      hits += std::abs(y + t * dy) < 10.0 && t * dz < 10.0;
    }
  return double(hits) / (kN * kN);
}

// A grey floor z = 0 under a sky of radiance L, with a perfect mirror wall x = 0 (10 m high, 20 m
// wide) beside the camera's view of the floor (x in about [0.27, 1.73]). From a floor point a
// fraction f of the cosine-distributed directions (WallFraction: about 0.44) meets the mirror and
// leaves upwards into the sky: a path tracer's sample of the caustic is πL with probability f, so
// the caustic is f·πL of the irradiance πL and the sample's variance (πL)²·f(1 − f). By brute force
// at the pilot's own lattice points, the pilot must give the mean of f and of f(1 − f). With 2^22
// photons and 1024 shadow rays per point the estimates' own noise is small: the fraction is within
// 0.2 % (tolerance 2 %). The relative variance is a mean of per-point ratios of noisy estimates,
// which leans high: +4.5 % here (tolerance 10 %), +9 % at the pilot's defaults (2^16 photons, 128
// shadow rays), where it only has to fall on the right side of a threshold with a wide margin.
TEST(CausticReach, AMirrorWallUnderASkyMatchesBruteForce) {
  SceneDescription scene;
  const uint32_t grey = AddMaterial(scene, Material{.name = "grey", .diffuse_reflectance = Rgb(0.5f)});
  const uint32_t mirror = AddMaterial(scene, Material{.name = "mirror", .specular_reflectance = Rgb(1.0f)});
  AddQuad(scene, {0, -10, 0}, {10, -10, 0}, {10, 10, 0}, {0, 10, 0}, grey);
  AddQuad(scene, {0, -10, 0}, {0, 10, 0}, {0, 10, 10}, {0, -10, 10}, mirror);  // facing +x
  AddSky(scene, 0.5f);
  const SceneRuntime runtime(scene);
  constexpr int kGrid = 32;
  const Camera camera(LookAtCamera({1.0f, 0, 2.0f}, {1.0f, 0, 0}, {1, 0, 0}, 40.0f, 32, 32));
  double f_sum = 0, variance_sum = 0;
  int points = 0;
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) {  // the pilot's lattice (pilot_lattice.h)
      const Ray ray = PilotLatticeRay(camera, kGrid, i, j);
      const Vec3 p = ray.origin + ray.direction * (-ray.origin.z / ray.direction.z);
      ASSERT_GT(p.x, 0.2f);
      const double f = WallFraction(p.x, p.y);
      f_sum += f;
      variance_sum += f * (1.0 - f);
      ++points;
    }
  const CausticReach reach = MeasureCausticReach(runtime, camera, kGrid, 1024, 1 << 22);
  EXPECT_EQ(reach.points, points);
  EXPECT_NEAR(reach.caustic_fraction, f_sum / points, 0.01);
  EXPECT_NEAR(reach.relative_caustic_variance, variance_sum / points, 0.025);
  EXPECT_EQ(reach.punctual_caustic_share, 0.0) << "no punctual light";
  std::printf("[ brute force ] caustic fraction %.4f (pilot %.4f), relative variance %.4f (pilot %.4f)\n",
              f_sum / points, reach.caustic_fraction, variance_sum / points, reach.relative_caustic_variance);

  scene.materials[mirror] = Material{.name = "grey too", .diffuse_reflectance = Rgb(0.5f)};
  const CausticReach grey_wall = MeasureCausticReach(SceneRuntime(scene), camera, kGrid, 128, 1 << 20);
  EXPECT_EQ(grey_wall.caustic_fraction, 0.0);
  EXPECT_EQ(grey_wall.relative_caustic_variance, 0.0);
}

// A glass ball (radius 0.3, centre 0.5 m up) on a grey floor, seen from above at an angle.
struct GlassBall {
  SceneDescription scene;
  CameraSpec camera = LookAtCamera({1.5f, 0.0f, 1.5f}, {0.0f, 0.0f, 0.2f}, {0, 0, 1}, 60.0f, 64, 48);
  GlassBall() {
    const uint32_t grey = AddMaterial(scene, Material{.name = "grey", .diffuse_reflectance = Rgb(0.5f)});
    const uint32_t glass =
        AddMaterial(scene, Material{.name = "glass", .specular_transmittance = Rgb(1.0f), .ior = 1.5f});
    AddQuad(scene, {-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}, grey);
    testing::AddSphere(scene, {0, 0, 0.5f}, 0.3f, 4, glass, false);
  }
  IntegratorEvidence Evidence() const { return SceneEvidence(scene, camera, JobRenderSettings()); }
};

TEST(CausticReach, TheRuleLeavesASkysCausticsToThePathTracerAndALampsToPhotons) {
  GlassBall sky;
  AddSky(sky.scene, 1.0f);
  const CausticReach by_sky = sky.Evidence().caustics;
  EXPECT_LT(by_sky.relative_caustic_variance, kNoisyCausticsAbove);
  EXPECT_GT(by_sky.caustic_fraction, 0.0) << "the ball's caustic is seen";
  EXPECT_EQ(by_sky.punctual_caustic_share, 0.0);
  EXPECT_EQ(ChooseIntegrator(sky.Evidence()).integrator, IntegratorKind::kPath);

  GlassBall lamp;  // a 10 cm lamp 2 m above the ball
  const uint32_t emitter = AddMaterial(lamp.scene, Material{.name = "lamp", .emission = Rgb(400.0f)});
  AddQuad(lamp.scene, {-0.05f, -0.05f, 2.5f}, {-0.05f, 0.05f, 2.5f}, {0.05f, 0.05f, 2.5f},
          {0.05f, -0.05f, 2.5f}, emitter, 0);
  lamp.scene.num_lights = 1;
  const CausticReach by_lamp = lamp.Evidence().caustics;
  EXPECT_GT(by_lamp.relative_caustic_variance, kNoisyCausticsAbove);
  EXPECT_EQ(by_lamp.punctual_caustic_share, 0.0);
  EXPECT_EQ(ChooseIntegrator(lamp.Evidence()).integrator, IntegratorKind::kPhotonMap);

  GlassBall point;
  AddPointLight(point.scene, {0, 0, 2.5}, 4.0f);
  const CausticReach by_point = point.Evidence().caustics;
  EXPECT_GT(by_point.punctual_caustic_share, kPunctualCausticsAbove);
  EXPECT_EQ(by_point.relative_caustic_variance, 0.0) << "a point light's caustic has no path-traced samples";
  EXPECT_EQ(ChooseIntegrator(point.Evidence()).integrator, IntegratorKind::kPhotonMap);
}

}  // namespace
}  // namespace pf
