// common/plan/task_executor.h: what the `auto` settings become for a scene ("auto
// defaults that choose from the scene and log why"), that explicit settings are never overridden;
// that tasks executed in any order merge to the local plan's image; that a cancel flag stops one.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include "common/core/error.h"
#include "common/plan/accumulator.h"
#include "common/plan/hierarchical.h"
#include "common/plan/task_executor.h"
#include "common/scene/scene_loader.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

SceneDescription Shipped(const std::string& rel) {
  return LoadScene((std::filesystem::path(PF_SOURCE_DIR) / "scenes" / rel).string());
}

const AutoChoice* Find(const std::vector<AutoChoice>& choices, const std::string& setting) {
  for (const AutoChoice& c : choices)
    if (c.setting == setting) return &c;
  return nullptr;
}

TEST(AutoSettings, OneLightGetsMonteCarloManyLightsGetPhotonDirect) {
  JobRenderSettings s;  // direct and caustic map are `auto` by default
  ASSERT_FALSE(s.direct.has_value());

  std::vector<AutoChoice> choices;
  const JobRenderSettings cornell = s.Resolved(Shipped("cornell-box/cornell-box.json"), &choices);
  ASSERT_TRUE(cornell.direct.has_value());
  EXPECT_EQ(*cornell.direct, DirectLightMode::kMonteCarlo);
  EXPECT_EQ(cornell.caustic, CausticMapMode::kOff) << "all-diffuse box: no caustic path";
  const AutoChoice* d = Find(choices, "direct");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->value, "monte-carlo");
  EXPECT_NE(d->reason.find("1 light"), std::string::npos) << d->reason;
  ASSERT_NE(Find(choices, "caustic-map"), nullptr);

  choices.clear();
  const SceneDescription rooms = Shipped("scene10/scene10.json");
  ASSERT_GE(rooms.num_lights, kPhotonDirectMinLights);
  const JobRenderSettings scene10 = s.Resolved(rooms, &choices);
  EXPECT_EQ(*scene10.direct, DirectLightMode::kPhotonDirect);
  d = Find(choices, "direct");
  ASSERT_NE(d, nullptr);
  EXPECT_NE(d->reason.find(std::to_string(rooms.num_lights) + " lights"), std::string::npos) << d->reason;

  choices.clear();
  const JobRenderSettings sphere = s.Resolved(Shipped("cornell-sphere/cornell-sphere.json"), &choices);
  EXPECT_EQ(sphere.caustic, CausticMapMode::kOn) << "mirror and glass spheres make caustics";
}

TEST(AutoSettings, ExplicitSettingsAreKeptAndNotReported) {
  JobRenderSettings s;
  s.direct = DirectLightMode::kNone;
  s.caustic = CausticMapMode::kOn;
  std::vector<AutoChoice> choices;
  const JobRenderSettings r = s.Resolved(Shipped("scene10/scene10.json"), &choices);
  EXPECT_EQ(*r.direct, DirectLightMode::kNone);
  EXPECT_EQ(r.caustic, CausticMapMode::kOn);
  EXPECT_TRUE(choices.empty());
}

TEST(AutoSettings, UnresolvedSettingsCannotConfigureAnIntegrator) {
  const JobRenderSettings s;
  EXPECT_THROW(s.IntegratorOptions(Bounds3()), std::logic_error);
  EXPECT_THROW(s.MapsOptions(), std::logic_error);
}

TEST(AutoSettings, ChapterFourSettingsReachTheIntegratorAndTheMaps) {
  JobRenderSettings s;
  s.direct = DirectLightMode::kPhotonDirect;
  s.shadow_rays = 7;
  s.photon_direct_k = 33;
  s.non_contributing = NonContributingMode::kEachOne;
  s.photon_direct_cache = 0.5f;
  s.local_pass_rays = 12;
  s.occlusion_test = true;
  s.adaptive_k_min = 9;
  Bounds3 b;
  b.Extend(Vec3(0, 0, 0));
  b.Extend(Vec3(3, 4, 0));  // diagonal 5
  const PhotonMapIntegratorOptions io = s.IntegratorOptions(b);
  EXPECT_EQ(io.direct, DirectLightMode::kPhotonDirect);
  EXPECT_EQ(io.photon_direct.samples, 7);
  EXPECT_EQ(io.photon_direct.k, 33);
  EXPECT_EQ(io.photon_direct.non_contributing, NonContributingMode::kEachOne);
  EXPECT_FLOAT_EQ(io.photon_direct.cache_radius_fraction, 0.5f);
  EXPECT_FLOAT_EQ(io.photon_direct.max_radius, 5.0f * kDirectPhotonRadiusFraction);
  EXPECT_FLOAT_EQ(io.direct_photons.max_radius, 5.0f * kDirectPhotonRadiusFraction);
  EXPECT_EQ(io.direct_photons.k, io.global.k);
  EXPECT_EQ(io.local_pass_rays, 12);
  EXPECT_TRUE(io.global.occlusion_test && io.caustic.occlusion_test);
  EXPECT_EQ(io.global.adaptive_k_min, 9);
  const PhotonMapsOptions mo = s.MapsOptions();
  EXPECT_TRUE(mo.separate_direct && mo.keep_light_ids && mo.keep_origins);
  // The maps differ from standalone ones, so the cache key must differ too.
  JobRenderSettings standalone = s;
  standalone.direct = DirectLightMode::kNone;
  standalone.occlusion_test = false;
  EXPECT_NE(s.MapFingerprint(), standalone.MapFingerprint());
}

// The precomputed sites' occlusion test (§4.1.1) reaches the sites' options, and the maps keep
// the photons' origins exactly when the sites need them.
TEST(AutoSettings, SiteOcclusionTestReachesTheSitesAndDecidesTheOrigins) {
  JobRenderSettings s;
  s.direct = DirectLightMode::kMonteCarlo;
  s.local_pass_rays = 8;
  s.local_pass_lookup = LocalPassLookup::kPrecomputed;
  Bounds3 b;
  b.Extend(Vec3(0, 0, 0));
  b.Extend(Vec3(1, 1, 1));
  ASSERT_TRUE(s.site_occlusion_test);  // the default
  EXPECT_TRUE(s.IntegratorOptions(b).precomputed.occlusion_test);
  EXPECT_TRUE(s.MapsOptions().keep_origins);
  JobRenderSettings off = s;
  off.site_occlusion_test = false;
  EXPECT_FALSE(off.IntegratorOptions(b).precomputed.occlusion_test);
  EXPECT_FALSE(off.MapsOptions().keep_origins);  // nothing else reads the origins
  EXPECT_NE(s.MapFingerprint(), off.MapFingerprint());
  off.occlusion_test = true;  // the camera path's own test still needs them
  EXPECT_TRUE(off.MapsOptions().keep_origins);
}

// A furnace: inside a glowing sphere (ρ = 0.5, Le = 1: L = 2 everywhere), seen from its centre.
SceneDescription GlowingSphere() {
  SceneDescription s;
  Material wall;
  wall.diffuse_reflectance = Rgb(0.5f);
  wall.emission = Rgb(1.0f);
  testing::AddSphere(s, Vec3(0.0f), 1.0f, 3, testing::AddMaterial(s, wall), true, 0, false);
  s.num_lights = 1;
  return s;
}

CameraSpec CentreCamera() {
  CameraSpec cam;
  cam.eye = Vec3(0.0f);
  cam.look_at = Vec3(0, 0, -1);
  cam.width = 12;
  cam.height = 8;
  return cam;
}

// Photon-map settings with `photons` photons and a small gather (k = 20): quick to render.
JobRenderSettings SmallGatherSettings(uint64_t photons) {
  JobRenderSettings settings;
  settings.photons = photons;
  settings.k = 20;
  return settings;
}

// Same plan and seed: any order of task execution gives the same image as RenderPlanLocally.
TEST(TaskExecutor, SkippingPlanIsOrderIndependent) {
  const SceneRuntime scene(GlowingSphere());
  const CameraSpec cam = CentreCamera();
  const JobRenderSettings settings = SmallGatherSettings(5000);
  const PlanSpec plan{.kind = PlanKind::kSkipping, .samples_per_pixel = 1, .stride = 2, .rounds = 2};
  const Image local = RenderPlanLocally(scene, cam, settings, plan, 77, 2);
  auto tasks = ExpandPlan(plan, cam.width, cam.height, 77);
  std::reverse(tasks.begin(), tasks.end());
  Accumulator acc(cam.width, cam.height);
  for (const TaskSpec& t : tasks) {
    const TaskOutput out = ExecuteTask(scene, "x", cam, settings, t, 1);
    acc.Add(PixelsOf(t.pixels, cam.width, cam.height), out.rgb_sums, out.samples);
  }
  const Image farm = acc.Resolve();
  for (size_t i = 0; i < local.size(); ++i) ASSERT_TRUE(local[i] == farm[i]) << i;
  EXPECT_GT(local[0].r, 0.5f);
}

// Tail tiles (PlanSpec::tail_tile_size) only regroup the last map's last row of pixels into
// smaller tasks: the image is bit-identical to the plan without them, also with the irradiance
// cache, whose per-16×16-block state would differ if a tail tile cut a block (renderer.h). The
// image (40×36, tile 32, tail 16) has a clipped last row and column, so the cut meets borders.
TEST(TaskExecutor, TailTilesGiveTheSameImage) {
  const SceneRuntime scene(GlowingSphere());
  CameraSpec cam = CentreCamera();
  cam.width = 40;
  cam.height = 36;
  JobRenderSettings settings = SmallGatherSettings(4000);
  settings.local_pass_rays = 4;
  settings.irradiance_cache_error = 0.3f;
  const PlanSpec plain{.kind = PlanKind::kMultipleMaps, .maps = 2, .samples_per_pixel = 1, .tile_size = 32};
  PlanSpec tail = plain;
  tail.tail_tile_size = 16;
  ASSERT_GT(CountTasks(tail, cam.width, cam.height), CountTasks(plain, cam.width, cam.height));
  const Image a = RenderPlanLocally(scene, cam, settings, plain, 5, 2);
  const Image b = RenderPlanLocally(scene, cam, settings, tail, 5, 1);
  for (size_t i = 0; i < a.size(); ++i) ASSERT_TRUE(a[i] == b[i]) << i;
  // Tail tiles of another side than a pixel block's multiple are refused, because they would not
  // be the same: the control below cuts every tile into 8×8 tasks by hand, through the blocks,
  // and the irradiance cache's image changes (so the equality above is not vacuous).
  PlanSpec bad = plain;
  bad.tail_tile_size = 8;
  EXPECT_THROW(RenderPlanLocally(scene, cam, settings, bad, 5, 1), InputError);
  Accumulator acc(cam.width, cam.height);
  for (const TaskSpec& t : ExpandPlan(plain, cam.width, cam.height, 5))
    for (uint32_t y = t.pixels.y0; y < t.pixels.y1; y += 8)
      for (uint32_t x = t.pixels.x0; x < t.pixels.x1; x += 8) {
        TaskSpec part = t;
        part.pixels.x0 = x;
        part.pixels.y0 = y;
        part.pixels.x1 = std::min(x + 8, t.pixels.x1);
        part.pixels.y1 = std::min(y + 8, t.pixels.y1);
        const TaskOutput out = ExecuteTask(scene, "x", cam, settings, part, 1);
        acc.Add(PixelsOf(part.pixels, cam.width, cam.height), out.rgb_sums, out.samples);
      }
  const Image cut = acc.Resolve();
  size_t differ = 0;
  for (size_t i = 0; i < a.size(); ++i) differ += a[i] == cut[i] ? 0 : 1;
  EXPECT_GT(differ, a.size() / 10) << "8x8 tasks through the 16x16 cache blocks should change the image";
}

// The hierarchical plan (§4.5) on a real scene: RenderPlanLocally equals executing its tasks in
// reverse order (static tasks, then the localization tasks the merged results imply), bit for bit.
TEST(TaskExecutor, HierarchicalPlanIsOrderIndependent) {
  const SceneRuntime scene(GlowingSphere());
  CameraSpec cam = CentreCamera();
  cam.width = 17;
  cam.height = 9;
  const JobRenderSettings settings = SmallGatherSettings(2000);
  const PlanSpec plan{.kind = PlanKind::kHierarchical,
                      .tile_size = 4,
                      .levels = 3,
                      .dims = 2,
                      .base_samples = 4,
                      .min_samples = 1};
  const Image local = RenderPlanLocally(scene, cam, settings, plan, 77, 2);
  HierarchicalAssembly acc(plan, cam.width, cam.height);
  size_t done = 0;
  for (;;) {
    std::vector<TaskSpec> tasks = HierarchicalTasks(plan, cam.width, cam.height, 77, acc);
    if (tasks.size() == done) break;
    for (size_t i = tasks.size(); i-- > done;) {
      const TaskOutput out = ExecuteTask(scene, "x", cam, settings, tasks[i], 1);
      acc.Add(tasks[i], PixelsOf(tasks[i].pixels, cam.width, cam.height), out.rgb_sums, out.samples);
    }
    done = tasks.size();
  }
  const Image farm = acc.Resolve();
  for (size_t i = 0; i < local.size(); ++i) ASSERT_TRUE(local[i] == farm[i]) << i;
  // A furnace: L = 2 everywhere; the hierarchy reconstructs it.
  for (size_t i = 0; i < local.size(); ++i) EXPECT_NEAR(local[i].g, 2.0f, 0.3f) << i;
}

// A cancel flag stops a task (photon tracing or rendering) with Cancelled, and a map whose
// tracing was cut short is never cached; without the flag the same task runs and caches its map.
TEST(TaskExecutor, CancelStopsTheTaskAndCachesNoMap) {
  const SceneRuntime scene(GlowingSphere());
  const CameraSpec cam = CentreCamera();
  const JobRenderSettings settings = SmallGatherSettings(20000);
  const TaskSpec task = ExpandPlan(PlanSpec{.kind = PlanKind::kMultipleMaps}, cam.width, cam.height, 5).at(0);
  PhotonMapCache cache(2);
  std::atomic<bool> cancel{true};
  EXPECT_THROW(ExecuteTask(scene, "x", cam, settings, task, 1, &cache, nullptr, &cancel), Cancelled);
  EXPECT_EQ(cache.size(), 0u) << "a cut-short map must not be reused";
  JobRenderSettings path = settings;
  path.integrator = IntegratorKind::kPath;
  EXPECT_THROW(ExecuteTask(scene, "x", cam, path, task, 1, &cache, nullptr, &cancel), Cancelled);

  cancel = false;
  const TaskOutput out = ExecuteTask(scene, "x", cam, settings, task, 1, &cache, nullptr, &cancel);
  EXPECT_EQ(out.pixels, uint64_t(cam.width * cam.height));
  EXPECT_EQ(cache.size(), 1u);
}

}  // namespace
}  // namespace pf
