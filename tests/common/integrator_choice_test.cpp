// `integrator auto` (common/render/integrator_choice.h) and its pilot (light_reach.h; the caustic
// pilot's own tests are caustic_reach_test.cpp): the pilot's
// fractions against geometry worked out by hand, the rule's branches, and what it chooses for the
// shipped scenes with references (the choices docs/results/time-budget.md measures).

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <cmath>
#include <filesystem>

#include "common/camera/camera.h"
#include "common/render/integrator_choice.h"
#include "common/render/light_reach.h"
#include "common/render/pilot_lattice.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;
using ::testing::HasSubstr;
using testing::LookAtCamera;

constexpr int kGrid = 64;

// The pilot's lattice (pilot_lattice.h): one camera ray through each cell centre of a kGrid × kGrid
// grid over the image.
template <typename Visit>
void ForEachLatticeRay(const Camera& camera, const Visit& visit) {
  for (int j = 0; j < kGrid; ++j)
    for (int i = 0; i < kGrid; ++i) visit(PilotLatticeRay(camera, kGrid, i, j));
}

// The floor z = 0 under a small light 1 m up (FloorUnderSquareLight) with an opaque square of side
// `blocker` centred 0.5 m up; the camera, 0.25 m up under the square, looks straight down and sees
// only floor. The umbra is the square scaled by 1/(1 − 0.5) = 2 about the light's foot point.
TEST(LightReach, LitFractionIsTheFloorOutsideTheShadowOfABlocker) {
  SceneDescription scene = testing::FloorUnderSquareLight(0.002f);
  const uint32_t grey = AddMaterial(scene, Material{.name = "blocker", .diffuse_reflectance = Rgb(0.5f)});
  const float b = 0.05f;
  AddQuad(scene, {-b, -b, 0.5f}, {b, -b, 0.5f}, {b, b, 0.5f}, {-b, b, 0.5f}, grey);
  const CameraSpec spec = LookAtCamera({0.0f, 0.0f, 0.25f}, {0.0f, 0.0f, 0.0f}, {0, 1, 0}, 90.0f, 64, 64);
  const SceneRuntime runtime(scene);
  const Camera camera(spec);
  const LightReach reach = MeasureLightReach(runtime, camera, 0.0f);

  // By hand: where each lattice ray meets the floor, and whether that point is in the umbra.
  int floor_points = 0, shadowed = 0;
  ForEachLatticeRay(camera, [&](const Ray& ray) {
    const float t = -ray.origin.z / ray.direction.z;
    const Vec3 p = ray.origin + ray.direction * t;
    ++floor_points;
    shadowed += std::abs(p.x) < 2.0f * b && std::abs(p.y) < 2.0f * b;
  });
  ASSERT_EQ(reach.points, floor_points);
  const double expected = 1.0 - double(shadowed) / double(floor_points);
  EXPECT_NEAR(expected, 1.0 - 0.4 * 0.4, 0.02) << "the umbra is 0.2 m of the 0.5 m seen";
  // The light's 4 mm sets a penumbra of 4 mm: at most a row of lattice points on each edge.
  EXPECT_NEAR(reach.lit_fraction, expected, (4.0 * 26 + 8) / double(floor_points));
  EXPECT_EQ(reach.leak_fraction, 0.0) << "no leak distance, no leak test";
}

// Two rooms on one floor z = 0, a wall of thickness `t` (x in [0, t], 2 m high) between them; the
// light (facing down, 1.9 m up) is in room B (x > t), the camera in room A looks at the wall's foot.
// Every point of room A is unlit; a photon search of radius r at a floor point d in front of the
// wall reaches into room B when the pilot's ray towards the wall (azimuth 0, elevation
// asin 0.2) gets through: (d + t) / cos(elevation) < r.
struct TwoRooms {
  SceneDescription scene;
  CameraSpec camera = LookAtCamera({-1.2f, 0.0f, 0.9f}, {-0.2f, 0.0f, 0.0f}, {0, 0, 1}, 60.0f, 64, 64);
  // t = 0: the wall is one sheet (a polygon with nothing behind it, as MGF rooms are often made).
  explicit TwoRooms(float t) {
    const uint32_t grey = AddMaterial(scene, Material{.name = "grey", .diffuse_reflectance = Rgb(0.5f)});
    const uint32_t light = AddMaterial(scene, Material{.name = "light", .emission = Rgb(10.0f)});
    AddQuad(scene, {-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}, grey);
    AddQuad(scene, {0, -5, 0}, {0, -5, 2}, {0, 5, 2}, {0, 5, 0}, grey);  // room A's face, normal -x
    if (t > 0) {
      AddQuad(scene, {t, -5, 0}, {t, 5, 0}, {t, 5, 2}, {t, -5, 2}, grey);  // room B's face, normal +x
      AddQuad(scene, {0, -5, 2}, {0, 5, 2}, {t, 5, 2}, {t, -5, 2}, grey);  // the top
    }
    AddQuad(scene, {2, -0.3f, 1.9f}, {2, 0.3f, 1.9f}, {3, 0.3f, 1.9f}, {3, -0.3f, 1.9f}, light, 0);
    scene.num_lights = 1;
  }
};

TEST(LightReach, LeakFractionIsTheFloorWithinReachOfTheRoomBehindAThinWall) {
  const float r = 0.5f;
  for (const float t : {0.0f, 0.05f, 0.2f}) {
    const TwoRooms rooms(t);
    const SceneRuntime runtime(rooms.scene);
    const Camera camera(rooms.camera);
    const LightReach reach = MeasureLightReach(runtime, camera, r);
    int points = 0, leaking = 0, edge = 0;
    // d below this leaks: the probe must still have more than a step (light_reach.cpp) left beyond.
    const float step = std::max(1e-3f * r, 4.0f * runtime.accel.epsilon());
    const float reach_x = (r - step) * std::sqrt(1.0f - 0.04f) - t;
    ForEachLatticeRay(camera, [&](const Ray& ray) {
      const float t_floor = -ray.origin.z / ray.direction.z;
      const float t_wall = -ray.origin.x / ray.direction.x;
      if (ray.direction.x > 0.0f && t_wall < t_floor) {
        ++points;  // the wall's face: its probes go back into room A
        return;
      }
      const float d = -(ray.origin.x + ray.direction.x * t_floor);
      ++points;
      leaking += d < reach_x;
      edge += std::abs(d - reach_x) < 0.01f;
    });
    ASSERT_EQ(reach.points, points) << "t " << t;
    EXPECT_EQ(reach.lit_fraction, 0.0) << "the wall hides the light from all of room A";
    ASSERT_GT(leaking, 100) << "the lattice must see the wall's foot";
    // The lattice's rows lie at constant d: at most half the rows near the boundary may differ.
    EXPECT_NEAR(reach.leak_fraction, double(leaking) / points, double(edge / 2 + 1) / points) << "t " << t;
  }
  // A wall thicker than the search radius: nothing from room B is found.
  const TwoRooms thick(0.6f);
  const SceneRuntime runtime(thick.scene);
  EXPECT_EQ(MeasureLightReach(runtime, Camera(thick.camera), r).leak_fraction, 0.0);
}

TEST(LightReach, IsTheSameOnAnyThreadCount) {
  const TwoRooms rooms(0.05f);
  const SceneRuntime runtime(rooms.scene);
  const LightReach a = MeasureLightReach(runtime, Camera(rooms.camera), 0.5f);
  LightReach b;
  tbb::task_arena(1).execute([&] { b = MeasureLightReach(runtime, Camera(rooms.camera), 0.5f); });
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.lit_fraction, b.lit_fraction);
  EXPECT_EQ(a.leak_fraction, b.leak_fraction);
}

IntegratorEvidence Evidence(double lit, double leak, int lights = 1) {
  IntegratorEvidence e;
  e.reach.points = 1000;
  e.reach.lit_fraction = lit;
  e.reach.leak_fraction = leak;
  e.lights = lights;
  return e;
}

TEST(IntegratorChoice, EachRuleChoosesAndSaysWhy) {
  const IntegratorChoice lit = ChooseIntegrator(Evidence(0.9, 0.0));
  EXPECT_EQ(lit.integrator, IntegratorKind::kPath);
  ASSERT_EQ(lit.choices.size(), 1u);
  EXPECT_EQ(lit.choices[0].setting, "integrator");
  EXPECT_EQ(lit.choices[0].value, "path");
  EXPECT_THAT(lit.choices[0].reason, HasSubstr("90% of the 1000 surface points"));

  IntegratorEvidence specular = Evidence(0.9, 0.0);
  specular.specular_surfaces = true;
  EXPECT_EQ(ChooseIntegrator(specular).integrator, IntegratorKind::kPhotonMap) << "no caustic evidence";
  EXPECT_THAT(ChooseIntegrator(specular).choices[0].reason, HasSubstr("no evidence"));
  specular.caustics.points = 1000;
  EXPECT_EQ(ChooseIntegrator(specular).integrator, IntegratorKind::kPath) << "caustics a path tracer finds";
  EXPECT_THAT(ChooseIntegrator(specular).choices[0].reason,
              HasSubstr("a path tracer renders their caustics"));
  specular.caustics.relative_caustic_variance = kNoisyCausticsAbove;
  EXPECT_EQ(ChooseIntegrator(specular).integrator, IntegratorKind::kPath);
  specular.caustics.relative_caustic_variance = kNoisyCausticsAbove * 1.01;
  EXPECT_EQ(ChooseIntegrator(specular).integrator, IntegratorKind::kPhotonMap) << "noisy caustics";
  EXPECT_THAT(ChooseIntegrator(specular).choices[0].reason, HasSubstr("a path tracer finds by chance"));
  specular.caustics.relative_caustic_variance = 0.0;
  specular.caustics.punctual_caustic_share = kPunctualCausticsAbove;
  EXPECT_EQ(ChooseIntegrator(specular).integrator, IntegratorKind::kPath);
  specular.caustics.punctual_caustic_share = kPunctualCausticsAbove * 1.01;
  EXPECT_EQ(ChooseIntegrator(specular).integrator, IntegratorKind::kPhotonMap)
      << "caustics of punctual lights";
  EXPECT_THAT(ChooseIntegrator(specular).choices[0].reason, HasSubstr("a path tracer never finds"));
  IntegratorEvidence unused = Evidence(0.9, 0.0);
  unused.caustics.punctual_caustic_share = 1.0;
  EXPECT_EQ(ChooseIntegrator(unused).integrator, IntegratorKind::kPath) << "no mirror or glass, no caustics";

  const IntegratorChoice many = ChooseIntegrator(Evidence(0.9, 0.0, 100));
  EXPECT_EQ(many.integrator, IntegratorKind::kPath) << "many lights, all of them in view";
  EXPECT_THAT(many.choices[0].reason, HasSubstr("100 lights"));

  const IntegratorChoice dark = ChooseIntegrator(Evidence(kIndirectlyLitBelow - 0.01, 0.0));
  EXPECT_EQ(dark.integrator, IntegratorKind::kPhotonMap);
  EXPECT_FALSE(dark.occlusion_test) << "no leak seen";
  EXPECT_EQ(ChooseIntegrator(Evidence(kIndirectlyLitBelow, 0.0)).integrator, IntegratorKind::kPath);

  IntegratorEvidence nothing_seen = Evidence(0.0, 0.0);
  nothing_seen.reach.points = 0;
  EXPECT_EQ(ChooseIntegrator(nothing_seen).integrator, IntegratorKind::kPath)
      << "a camera that sees only lights and mirrors gives no evidence of indirect light";

  IntegratorEvidence given = Evidence(0.9, 0.0);
  given.photon_map_settings_given = true;
  EXPECT_EQ(ChooseIntegrator(given).integrator, IntegratorKind::kPhotonMap);
}

TEST(IntegratorChoice, OcclusionTestOnlyForAPhotonMapWithLeaksAndOnlyIfNotGiven) {
  const IntegratorChoice leaky = ChooseIntegrator(Evidence(0.1, kLeakyAbove + 0.01));
  EXPECT_TRUE(leaky.occlusion_test);
  ASSERT_EQ(leaky.choices.size(), 2u);
  EXPECT_EQ(leaky.choices[1].setting, "occlusion-test");
  EXPECT_EQ(leaky.choices[1].value, "true");
  EXPECT_FALSE(ChooseIntegrator(Evidence(0.1, kLeakyAbove)).occlusion_test);
  EXPECT_FALSE(ChooseIntegrator(Evidence(0.9, 0.5)).occlusion_test) << "the path tracer does not bleed";
  IntegratorEvidence given = Evidence(0.1, 0.5);
  given.occlusion_test_given = true;
  EXPECT_FALSE(ChooseIntegrator(given).occlusion_test);
  EXPECT_EQ(ChooseIntegrator(given).choices.size(), 1u);
  given = Evidence(0.9, 0.5);
  given.photon_map_settings_given = true;
  EXPECT_TRUE(ChooseIntegrator(given).occlusion_test) << "photon-map settings given, leaks seen";
}

TEST(IntegratorChoice, SpecularSurfacesAreDeltaLobesOnly) {
  SceneDescription s = testing::FloorUnderSquareLight(0.5f);
  EXPECT_FALSE(SceneHasSpecularSurfaces(s));
  s.materials.push_back(
      Material{.name = "glossy", .specular_reflectance = Rgb(0.5f), .specular_roughness = 0.2f});
  EXPECT_FALSE(SceneHasSpecularSurfaces(s)) << "a Ward lobe is sampled by next-event estimation";
  s.materials.push_back(Material{.name = "mirror", .specular_reflectance = Rgb(0.9f)});
  EXPECT_TRUE(SceneHasSpecularSurfaces(s));
  s.materials.pop_back();
  s.materials.push_back(Material{.name = "glass", .specular_transmittance = Rgb(0.9f), .ior = 1.5f});
  EXPECT_TRUE(SceneHasSpecularSurfaces(s));
}

// The shipped scenes with references, with their first camera and the default photons and k (the
// manifests' larger maps search smaller radii, and SceneEvidence takes the larger): the choices
// docs/results/time-budget.md measures.
IntegratorChoice ChoiceFor(const std::string& manifest) {
  const SceneDescription scene = LoadScene(std::filesystem::path(PF_SOURCE_DIR) / "scenes" / manifest);
  return ChooseIntegrator(SceneEvidence(scene, scene.cameras.at(0), JobRenderSettings()));
}

TEST(IntegratorChoice, ShippedScenes) {
  EXPECT_EQ(ChoiceFor("cornell-box/cornell-box.json").integrator, IntegratorKind::kPath);
  EXPECT_EQ(ChoiceFor("scene8/scene8.json").integrator, IntegratorKind::kPath);
  for (const char* caustic :
       {"cornell-sphere/cornell-sphere.json", "scene5/scene5.json", "bathroom/bathroom.json"}) {
    const IntegratorChoice c = ChoiceFor(caustic);
    EXPECT_EQ(c.integrator, IntegratorKind::kPhotonMap) << caustic;
    EXPECT_FALSE(c.occlusion_test) << caustic;
  }
  EXPECT_EQ(ChoiceFor("conference/conference.json").integrator, IntegratorKind::kPath) << "8 lights in view";
  EXPECT_EQ(ChoiceFor("blender-studio/blender-studio.json").integrator, IntegratorKind::kPath)
      << "glass, but the caustics are the sky's";
  EXPECT_EQ(ChoiceFor("office3/office3.json").integrator, IntegratorKind::kPhotonMap)
      << "a polished desk under a bare bulb: the path tracer's image is fireflies";
  for (const char* leaky : {"invisibledate/invisibledate.json", "scene10/scene10.json"}) {
    const IntegratorChoice c = ChoiceFor(leaky);
    EXPECT_EQ(c.integrator, IntegratorKind::kPhotonMap) << leaky;
    EXPECT_TRUE(c.occlusion_test) << leaky;
  }
}

}  // namespace
}  // namespace pf
