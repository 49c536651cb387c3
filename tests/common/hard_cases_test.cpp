// Numerically hard scenes (docs/renderer.md; "Hard cases"; results in docs/results/hard_cases.md): each
// renders a finite image with the analytic mean where one exists, or fails with a clear error —
// never NaN, a hang or a crash.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/core/rng.h"
#include "common/lights/light_sampler.h"
#include "common/photon/brute_force.h"
#include "common/photon/photon_map_factory.h"
#include "common/photon/photon_maps.h"
#include "common/plan/task_executor.h"
#include "common/render/job_render_settings.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_frame.h"
#include "common/scene/scene_loader.h"
#include "tests/common/test_scenes.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;

struct RenderResult {
  double mean = 0;         // mean over pixels and channels
  uint64_t nonfinite = 0;  // samples the renderer dropped as NaN/Inf
  bool finite = true;      // every pixel finite
};

RenderResult Summarise(const Image& img, const RenderStats& stats) {
  RenderResult r;
  double sum = 0;
  for (const Rgb& c : img.pixels()) {
    r.finite = r.finite && c.IsFinite();
    sum += double(c.Mean());
  }
  r.mean = sum / double(img.size());
  r.nonfinite = stats.nonfinite_samples;
  return r;
}

// Renders as `pf render --local-only` does (SceneRuntime, RenderPlanLocally, the product's
// default settings resolved for the scene): one map of `photons` photons and k nearest for the
// photon map, `spp` samples per pixel. A description built here in world coordinates is placed
// in its frame first, as a loader places what it reads (scene_frame.h; a no-op for scenes around
// the origin and for loaded ones).
RenderResult RenderMean(SceneDescription scene, const CameraSpec& camera, IntegratorKind kind, uint32_t spp,
                        uint64_t photons = 50000, int k = 50, uint64_t seed = 1) {
  if (scene.origin == Vec3d()) PlaceInSceneFrame(&scene);
  const SceneRuntime runtime(std::move(scene));
  JobRenderSettings settings;
  settings.integrator = kind;
  settings.photons = photons;
  settings.k = k;
  const PlanSpec plan{.kind = PlanKind::kMultipleMaps, .maps = 1, .samples_per_pixel = spp};
  LocalRenderTotals totals;
  const Image img = RenderPlanLocally(runtime, camera, settings, plan, seed, 0, nullptr, &totals);
  RenderStats stats;
  stats.nonfinite_samples = totals.nonfinite_samples;  // the samples RenderPixels dropped as NaN/Inf
  return Summarise(img, stats);
}

// A closed room 2 m wide (red left wall, green right wall, white elsewhere) with a 0.5 m square
// light 1/8 m below the ceiling and a white block on the floor; the camera stands inside by the
// front wall. Every coordinate is a multiple of 1/8, so translating the room by up to 2^20 in
// each axis is exact in float: a translated render sees the very same geometry.
using RoomSetup = testing::SceneWithCamera;

RoomSetup SnappedRoom() {
  RoomSetup r;
  SceneDescription& s = r.scene;
  const uint32_t white = AddMaterial(s, Material{.name = "white", .diffuse_reflectance = Rgb(0.7f)});
  const uint32_t red = AddMaterial(s, Material{.name = "red", .diffuse_reflectance = Rgb(0.6f, 0.1f, 0.1f)});
  const uint32_t green =
      AddMaterial(s, Material{.name = "green", .diffuse_reflectance = Rgb(0.1f, 0.6f, 0.1f)});
  const uint32_t lamp = AddMaterial(s, Material{.name = "lamp", .emission = Rgb(12.0f)});
  // Walls, front faces inwards.
  AddQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}, white);    // floor (+y)
  AddQuad(s, {-1, 2, -1}, {1, 2, -1}, {1, 2, 1}, {-1, 2, 1}, white);    // ceiling (-y)
  AddQuad(s, {-1, 0, -1}, {1, 0, -1}, {1, 2, -1}, {-1, 2, -1}, white);  // back (+z)
  AddQuad(s, {-1, 0, 1}, {-1, 2, 1}, {1, 2, 1}, {1, 0, 1}, white);      // front (-z)
  AddQuad(s, {-1, 0, -1}, {-1, 2, -1}, {-1, 2, 1}, {-1, 0, 1}, red);    // left (+x)
  AddQuad(s, {1, 0, -1}, {1, 0, 1}, {1, 2, 1}, {1, 2, -1}, green);      // right (-x)
  // The light, facing down.
  AddQuad(s, {-0.25f, 1.875f, -0.25f}, {0.25f, 1.875f, -0.25f}, {0.25f, 1.875f, 0.25f},
          {-0.25f, 1.875f, 0.25f}, lamp, 0);
  s.num_lights = 1;
  // A block 0.5 x 0.75 x 0.5 (outward faces, no bottom).
  const float x0 = -0.625f, x1 = -0.125f, y1 = 0.75f, z0 = -0.625f, z1 = -0.125f;
  AddQuad(s, {x0, y1, z0}, {x0, y1, z1}, {x1, y1, z1}, {x1, y1, z0}, white);  // top
  AddQuad(s, {x0, 0, z1}, {x1, 0, z1}, {x1, y1, z1}, {x0, y1, z1}, white);    // +z
  AddQuad(s, {x1, 0, z0}, {x0, 0, z0}, {x0, y1, z0}, {x1, y1, z0}, white);    // -z
  AddQuad(s, {x1, 0, z1}, {x1, 0, z0}, {x1, y1, z0}, {x1, y1, z1}, white);    // +x
  AddQuad(s, {x0, 0, z0}, {x0, 0, z1}, {x0, y1, z1}, {x0, y1, z0}, white);    // -x
  r.camera.eye = Vec3d(0.0, 1.0, 0.875);
  r.camera.look_at = Vec3d(0.0, 0.75, -1.0);
  r.camera.vfov_degrees = 75.0f;
  r.camera.width = r.camera.height = 24;
  return r;
}

void Translate(RoomSetup& r, const Vec3& offset) {
  for (Vec3& p : r.scene.positions) p += offset;
  r.camera.eye += Vec3d(offset);
  r.camera.look_at += Vec3d(offset);
}

// Path tracer and photon map traced in world coordinates (EmbreeScene built from the translated
// description directly, no local frame): only the ray offsets stand between the renderer and
// self-intersection. Before the local frame the offset was 2^-15 of the largest coordinate (3 m at
// 1e5, 30 m at 1e6: rays left the 2 m room): the path tracer gave 0.0342 and 0.0553 here instead
// of 0.1629. The untranslated room's seeds differ by < 0.1 % (path, Sobol) and ~1 % (photon map,
// 50k photons), so 1 % and 3 % are > 3σ bounds.
RenderResult RenderWorldMean(const SceneDescription& scene, const CameraSpec& camera, IntegratorKind kind,
                             uint32_t spp, uint64_t photons = 50000, int k = 50) {
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  RenderStats stats;
  if (kind == IntegratorKind::kPath) {
    const PathTracer tracer(accel, lights);
    const Image img = RenderImage(tracer, Camera(camera), RenderOptions{.spp = spp, .seed = 1}, &stats);
    return Summarise(img, stats);
  }
  JobRenderSettings settings;
  settings.photons = photons;
  settings.k = k;
  settings = settings.Resolved(scene);
  PhotonMapsOptions mo = settings.MapsOptions();
  mo.tracing.map_seed = 1;
  const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
  const PhotonMapIntegrator integrator(accel, &lights, maps, settings.IntegratorOptions(accel.bounds()));
  const Image img = RenderImage(integrator, Camera(camera), RenderOptions{.spp = spp, .seed = 1}, &stats);
  return Summarise(img, stats);
}

class HardCasesTranslatedWorld : public ::testing::TestWithParam<float> {};

// The ray-offset code steps floats by their bits (NextFloatUp/Down, common/accel/ray.h); it must
// agree with std::nextafter everywhere: zeros of both signs, subnormals, normals of every
// magnitude, the largest float (up: infinity) and random bit patterns.
TEST(HardCasesRayOffset, NextFloatMatchesNextafter) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  std::vector<float> values = {0.0f,
                               -0.0f,
                               std::numeric_limits<float>::denorm_min(),
                               -std::numeric_limits<float>::denorm_min(),
                               std::numeric_limits<float>::min(),
                               1.0f,
                               -1.0f,
                               1e6f,
                               -1e6f,
                               3.0e38f,
                               std::numeric_limits<float>::max(),
                               -std::numeric_limits<float>::max()};
  Rng rng = Rng::ForKey(7);
  for (int i = 0; i < 100000; ++i) {
    const float v = std::bit_cast<float>(rng.NextU32());
    if (std::isfinite(v)) values.push_back(v);
  }
  for (float v : values) {
    ASSERT_EQ(std::bit_cast<uint32_t>(NextFloatUp(v)), std::bit_cast<uint32_t>(std::nextafter(v, kInf))) << v;
    ASSERT_EQ(std::bit_cast<uint32_t>(NextFloatDown(v)), std::bit_cast<uint32_t>(std::nextafter(v, -kInf)))
        << v;
  }
  EXPECT_EQ(Ulp(1.0f), 0x1p-23f);
  EXPECT_EQ(Ulp(-1e6f), 0.0625f);
  EXPECT_GT(Ulp(std::numeric_limits<float>::max()), 0.0f);
  EXPECT_TRUE(std::isfinite(Ulp(std::numeric_limits<float>::max())));
}

// OffsetRayOrigin (the SSE4.1 form on this build, else the scalar one) and OffsetRayOriginScalar
// must both give the offset defined with libm's nextafter: p + n·RayOffset, each coordinate that
// moved stepped one float further away from p, for finite points and normals: normals with zero,
// negative-zero and mixed-sign components, points at, near and far from the origin (on and off
// zero coordinates, so the ±0 steps happen), scene floors from tiny to large.
TEST(HardCasesRayOffset, OffsetRayOriginStepsEachMovedCoordinateAway) {
  constexpr float kInf = std::numeric_limits<float>::infinity();
  const auto same_bits = [](const Vec3& a, const Vec3& b) {
    return std::bit_cast<uint32_t>(a.x) == std::bit_cast<uint32_t>(b.x) &&
           std::bit_cast<uint32_t>(a.y) == std::bit_cast<uint32_t>(b.y) &&
           std::bit_cast<uint32_t>(a.z) == std::bit_cast<uint32_t>(b.z);
  };
  Rng rng(5, 9);
  const std::vector<float> scales = {0.0f, 1e-30f, 1e-6f, 1.0f, 3.7f, 1e5f, 1e6f};
  int moved_to_other_sign = 0;
  for (int i = 0; i < 200000; ++i) {
    const float scale = scales[size_t(i) % scales.size()];
    Vec3 p(scale * (2 * rng.Uniform() - 1), scale * (2 * rng.Uniform() - 1), scale * (2 * rng.Uniform() - 1));
    if (i % 5 == 0) p.y = i % 10 ? 0.0f : -0.0f;
    Vec3 n = Normalize(Vec3(2 * rng.Uniform() - 1, 2 * rng.Uniform() - 1, 2 * rng.Uniform() - 1));
    switch (i % 4) {
      case 0:
        n = Vec3(0.0f, i % 8 ? 1.0f : -1.0f, 0.0f);
        break;
      case 1:
        n = Vec3(-0.0f, 0.0f, i % 8 == 1 ? -1.0f : 1.0f);
        break;
      default:
        break;
    }
    const float eps = i % 3 == 0 ? 1e-30f : i % 3 == 1 ? 1e-6f : 0.5f;
    const Vec3 offset = n * RayOffset(p, n, eps);
    Vec3 expected = p + offset;
    for (int k = 0; k < 3; ++k)
      if (offset[k] != 0.0f) expected[k] = std::nextafter(expected[k], offset[k] > 0.0f ? kInf : -kInf);
    const Vec3 a = OffsetRayOrigin(p, n, eps), b = OffsetRayOriginScalar(p, n, eps);
    ASSERT_TRUE(same_bits(a, expected)) << i;
    ASSERT_TRUE(same_bits(b, expected)) << i;
    moved_to_other_sign += std::signbit(a.y) != std::signbit(p.y);
  }
  EXPECT_GT(moved_to_other_sign, 1000);  // the ±0 and sign-crossing steps were exercised
}

TEST_P(HardCasesTranslatedWorld, RayOffsetsHoldFarFromTheOrigin) {
  const RoomSetup original = SnappedRoom();
  RoomSetup moved = SnappedRoom();
  Translate(moved, Vec3(GetParam()));
  const RenderResult p0 = RenderWorldMean(original.scene, original.camera, IntegratorKind::kPath, 64);
  const RenderResult p1 = RenderWorldMean(moved.scene, moved.camera, IntegratorKind::kPath, 64);
  ASSERT_TRUE(p1.finite);
  EXPECT_EQ(p1.nonfinite, 0u);
  EXPECT_NEAR(p1.mean, p0.mean, 0.01 * p0.mean) << "path tracer, translated by " << GetParam();
  // The photon map in world coordinates only at 1e5: at 1e6 the hit points themselves lie on a
  // 6.25 cm lattice and the density estimate collapses (the local frame of SceneRuntime is the
  // fix, tested below).
  if (GetParam() <= 1e5f) {
    const RenderResult m0 = RenderWorldMean(original.scene, original.camera, IntegratorKind::kPhotonMap, 16);
    const RenderResult m1 = RenderWorldMean(moved.scene, moved.camera, IntegratorKind::kPhotonMap, 16);
    ASSERT_TRUE(m1.finite);
    EXPECT_NEAR(m1.mean, m0.mean, 0.03 * m0.mean) << "photon map, translated by " << GetParam();
  }
}

INSTANTIATE_TEST_SUITE_P(Offsets, HardCasesTranslatedWorld, ::testing::Values(1e5f, 1e6f));

// The product's path (the scene's frame, RenderPlanLocally): the room translated by 1e5 or 1e6
// renders the original image to 1e-4 (same seeds; the original room, around the origin, is
// traced unmoved and the far one centred, so they differ only in rounding), with either
// integrator. Before the local frame (256-ulp offsets): path 0.0342 / 0.0553 and photon
// map 0.0341 / 0.0554 for 0.1629 / 0.1637; with the new offsets but without the local frame the
// photon map at 1e6 gave 0.0793 for 0.1614 (200k photons, k = 20: photons piled on the 6.25 cm
// float lattice).
class HardCasesTranslated : public ::testing::TestWithParam<float> {};

TEST_P(HardCasesTranslated, RendersLikeTheOriginal) {
  const RoomSetup original = SnappedRoom();
  RoomSetup moved = SnappedRoom();
  Translate(moved, Vec3(GetParam()));
  for (IntegratorKind kind : {IntegratorKind::kPath, IntegratorKind::kPhotonMap}) {
    const uint32_t spp = kind == IntegratorKind::kPath ? 32 : 8;
    const RenderResult a = RenderMean(original.scene, original.camera, kind, spp, 100000, 20);
    const RenderResult b = RenderMean(moved.scene, moved.camera, kind, spp, 100000, 20);
    ASSERT_TRUE(b.finite);
    EXPECT_GT(a.mean, 0.1);
    EXPECT_NEAR(b.mean, a.mean, 1e-4 * a.mean)
        << "integrator " << int(kind) << ", translated by " << GetParam();
  }
}

INSTANTIATE_TEST_SUITE_P(Offsets, HardCasesTranslated, ::testing::Values(1e5f, 1e6f));

// Only scenes far from the origin move: a scene around the origin keeps its coordinates (and
// its images, bit for bit); the far one is centred (exactly, here), and Camera moves the world
// camera by the same origin.
TEST(HardCasesTranslated, OnlyFarScenesGetAFrame) {
  const RoomSetup room = SnappedRoom();
  SceneDescription near = room.scene;
  PlaceInSceneFrame(&near);
  EXPECT_EQ(near.origin, Vec3d());
  EXPECT_EQ(near.positions, room.scene.positions);
  RoomSetup moved = SnappedRoom();
  Translate(moved, Vec3(1e6f, 0.0f, 0.0f));
  SceneDescription far = moved.scene;
  PlaceInSceneFrame(&far);
  EXPECT_EQ(far.origin, Vec3d(1e6, 1.0, 0.0));
  for (size_t i = 0; i < room.scene.positions.size(); ++i)
    ASSERT_EQ(far.positions[i], room.scene.positions[i] - Vec3(0.0f, 1.0f, 0.0f)) << i;
  EXPECT_EQ(Camera(moved.camera, far.origin).eye(), Vec3(room.camera.eye) - Vec3(0.0f, 1.0f, 0.0f));
}

// The shipped Cornell box translated by 1e5 and 1e6 in x, y and z *in its files*: the OBJ's
// vertices and the manifest's camera written as unrounded decimals (x + 1e6 = "1000000.99", not
// on the 6.25 cm float lattice there), loaded by LoadScene like any scene. The loaders keep the
// coordinates in double until the scene's frame is chosen (scene_frame.h), so the stored floats
// are the box's shape to float precision at its size (1e-7 m), and with the same seeds the image
// mean is the untranslated one's, with either integrator: measured equal to 6 digits; the bound
// is 0.1 % (the issue asks 1 %), so that the 1e5 case fails without the fix too. Before (loaders
// rounding world coordinates to float, then SceneRuntime's local frame): at 1e6 the light
// (y = 1.98) and the ceiling (1.99) rounded onto one plane, path 0.0887 and photon map 0.0873 for
// 0.1190 / 0.1200 (−25 % / −27 %), and at 1e5 −1.2 % / −0.6 % (docs/results/hard_cases.md).
std::string Decimal(double v) {
  char text[64];
  std::snprintf(text, sizeof text, "%.6f", v);  // the inputs have <= 6 decimals: exact
  return text;
}

SceneDescription LoadTranslatedCornellBox(const std::filesystem::path& dir, double t) {
  const std::filesystem::path shipped = std::filesystem::path(PF_SOURCE_DIR) / "scenes" / "cornell-box";
  std::filesystem::copy_file(shipped / "CornellBox-Original.mtl", dir / "CornellBox-Original.mtl");
  std::ifstream in(shipped / "CornellBox-Original.obj");
  std::ofstream obj(dir / "CornellBox-Original.obj");
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string keyword;
    double x, y, z;
    if (words >> keyword && keyword == "v" && words >> x >> y >> z)
      obj << "v " << Decimal(x + t) << " " << Decimal(y + t) << " " << Decimal(z + t) << "\n";
    else
      obj << line << "\n";
  }
  obj.close();
  const SceneDescription shipped_scene = LoadScene(shipped / "cornell-box.json");
  const CameraSpec& cam = shipped_scene.cameras.front();
  auto point = [&](const Vec3d& p) {
    std::ostringstream text;
    text << "[" << Decimal(p.x + t) << ", " << Decimal(p.y + t) << ", " << Decimal(p.z + t) << "]";
    return text.str();
  };
  std::ofstream manifest(dir / "cornell-box.json");
  manifest << "{\"version\": 1, \"geometry\": \"CornellBox-Original.obj\", \"cameras\": [{\"eye\": "
           << point(cam.eye) << ", \"look_at\": " << point(cam.look_at) << ", \"fov\": " << cam.vfov_degrees
           << "}]}\n";
  manifest.close();
  return LoadScene(dir / "cornell-box.json");
}

TEST_P(HardCasesTranslated, ShippedCornellBoxTranslatedInItsFilesRendersLikeTheOriginal) {
  const SceneDescription original =
      LoadScene(std::string(PF_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.json");
  test_util::TempDir dir("pf_hard_cases");
  const SceneDescription moved = LoadTranslatedCornellBox(dir.path(), double(GetParam()));
  EXPECT_NE(moved.origin, Vec3d());  // far: stored in its own frame
  CameraSpec cam = original.cameras.front(), moved_cam = moved.cameras.front();
  cam.width = cam.height = moved_cam.width = moved_cam.height = 24;
  for (IntegratorKind kind : {IntegratorKind::kPath, IntegratorKind::kPhotonMap}) {
    const uint32_t spp = kind == IntegratorKind::kPath ? 32 : 8;
    const RenderResult a = RenderMean(original, cam, kind, spp, 50000, 50);
    const RenderResult b = RenderMean(moved, moved_cam, kind, spp, 50000, 50);
    std::printf("[ means    ] translated by %g, %s: %.6f for %.6f\n", double(GetParam()),
                kind == IntegratorKind::kPath ? "path" : "photon map", b.mean, a.mean);
    ASSERT_TRUE(b.finite);
    EXPECT_GT(a.mean, 0.05);
    EXPECT_NEAR(b.mean, a.mean, 1e-3 * a.mean)
        << "integrator " << int(kind) << ", translated by " << GetParam();
  }
}

// Scale: the room scaled by 1e-4 and 1e5 about the origin renders like the original (radiance
// does not depend on the unit of length), with either integrator, in world coordinates.
class HardCasesScaled : public ::testing::TestWithParam<float> {};

TEST_P(HardCasesScaled, RendersLikeTheOriginal) {
  const RoomSetup original = SnappedRoom();
  RoomSetup scaled = SnappedRoom();
  testing::ScaleScene(scaled.scene, scaled.camera, GetParam());
  for (IntegratorKind kind : {IntegratorKind::kPath, IntegratorKind::kPhotonMap}) {
    const uint32_t spp = kind == IntegratorKind::kPath ? 64 : 16;
    const RenderResult a = RenderWorldMean(original.scene, original.camera, kind, spp);
    const RenderResult b = RenderWorldMean(scaled.scene, scaled.camera, kind, spp);
    ASSERT_TRUE(b.finite);
    EXPECT_NEAR(b.mean, a.mean, (kind == IntegratorKind::kPath ? 0.01 : 0.03) * a.mean)
        << "integrator " << int(kind) << ", scaled by " << GetParam();
  }
}

INSTANTIATE_TEST_SUITE_P(Scales, HardCasesScaled, ::testing::Values(1e-4f, 1e5f));

// ---------------------------------------------------------------------------------------------
// Degenerate and extreme inputs. Each renders with both integrators (RenderBoth) and must give a
// finite image with no NaN/Inf sample dropped; where the mean is known, it is checked.

struct BothMeans {
  RenderResult path, photon;
};

BothMeans RenderBoth(const SceneDescription& scene, const CameraSpec& camera, uint32_t path_spp = 64,
                     uint32_t photon_spp = 16, uint64_t photons = 50000, int k = 50) {
  BothMeans m;
  m.path = RenderMean(scene, camera, IntegratorKind::kPath, path_spp, photons, k);
  m.photon = RenderMean(scene, camera, IntegratorKind::kPhotonMap, photon_spp, photons, k);
  for (const RenderResult* r : {&m.path, &m.photon}) {
    EXPECT_TRUE(r->finite);
    EXPECT_EQ(r->nonfinite, 0u);
  }
  return m;
}

// Zero-area triangles (a repeated vertex, three collinear points, one emitting) in the room, and
// its back wall rebuilt from 4000 slivers (0.5 mm x 2 m, aspect 4000:1, which every ray at the
// back wall hits): nothing changes beyond noise.
TEST(HardCasesDegenerate, ZeroAreaAndSliverTrianglesChangeNothing) {
  const RoomSetup room = SnappedRoom();
  RoomSetup odd = SnappedRoom();
  SceneDescription& s = odd.scene;
  const uint32_t white = 0;
  const uint32_t lamp = AddMaterial(s, Material{.name = "degenerate lamp", .emission = Rgb(5.0f)});
  auto add = [&](Vec3 a, Vec3 b, Vec3 c, uint32_t material, uint32_t light) {
    const uint32_t base = uint32_t(s.positions.size());
    for (const Vec3& p : {a, b, c}) s.positions.push_back(p);
    testing::AddTriangle(s, base, base + 1, base + 2, material, light);
  };
  for (int i = 0; i < 20; ++i) {
    const float x = -0.9f + 0.09f * float(i), y = 0.1f + 0.09f * float(i);
    add({x, y, -0.5f}, {x, y, -0.5f}, {x + 0.3f, y, 0.2f}, white, kNoLight);  // repeated vertex
    add({x, y, 0.1f}, {x + 0.1f, y + 0.1f, 0.1f}, {x + 0.2f, y + 0.2f, 0.1f}, white, kNoLight);  // collinear
  }
  add({0, 1.5f, 0}, {0.1f, 1.5f, 0}, {0.2f, 1.5f, 0}, lamp, 1);  // a light of zero area
  s.num_lights = 2;
  // The back wall (the third quad: triangles 4 and 5) collapses to zero area, and slivers
  // replace it.
  for (size_t t : {4u, 5u}) s.triangles[t] = {s.triangles[t][0], s.triangles[t][0], s.triangles[t][0]};
  const int strips = 2000;
  for (int i = 0; i < strips; ++i) {
    const float x0 = -1.0f + 2.0f * float(i) / strips, x1 = -1.0f + 2.0f * float(i + 1) / strips;
    add({x0, 0, -1}, {x1, 0, -1}, {x1, 2, -1}, white, kNoLight);
    add({x0, 0, -1}, {x1, 2, -1}, {x0, 2, -1}, white, kNoLight);
  }
  const BothMeans a = RenderBoth(room.scene, room.camera);
  const BothMeans b = RenderBoth(odd.scene, odd.camera);
  EXPECT_NEAR(b.path.mean, a.path.mean, 0.01 * a.path.mean);
  EXPECT_NEAR(b.photon.mean, a.photon.mean, 0.03 * a.photon.mean);
}

// A scene whose only light has zero area emits no power: a black image, never NaN (the light
// sampler's pdf would divide by a zero power) and no crash.
TEST(HardCasesDegenerate, OnlyLightOfZeroArea) {
  RoomSetup r = SnappedRoom();
  SceneDescription& s = r.scene;
  const size_t lamp_tri = 12;  // the light quad's triangles (after the six walls)
  ASSERT_NE(s.triangle_light[lamp_tri], kNoLight);
  for (size_t t : {lamp_tri, lamp_tri + 1})
    s.triangles[t] = {s.triangles[t][0], s.triangles[t][1], s.triangles[t][1]};
  const BothMeans m = RenderBoth(s, r.camera, 16, 4, 20000);
  EXPECT_EQ(m.path.mean, 0.0);
  EXPECT_EQ(m.photon.mean, 0.0);
}

// Coincident faces: a black floor exactly on the white one. Whichever face a ray meets, the
// image is finite and lies between the all-white and the all-black floor.
TEST(HardCasesDegenerate, CoincidentFacesStayBetweenTheirMaterials) {
  RoomSetup white = SnappedRoom();
  RoomSetup both = SnappedRoom();
  RoomSetup black = SnappedRoom();
  const uint32_t dark = AddMaterial(both.scene, Material{.name = "black"});
  AddQuad(both.scene, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}, dark);
  const uint32_t dark2 = AddMaterial(black.scene, Material{.name = "black"});
  for (size_t t = 0; t < 2; ++t) black.scene.triangle_material[t] = dark2;  // the floor's two triangles
  const BothMeans w = RenderBoth(white.scene, white.camera);
  const BothMeans m = RenderBoth(both.scene, both.camera);
  const BothMeans b = RenderBoth(black.scene, black.camera);
  EXPECT_LT(b.path.mean, w.path.mean * 0.95) << "the floor's colour matters";
  EXPECT_GE(m.path.mean, b.path.mean * 0.99);
  EXPECT_LE(m.path.mean, w.path.mean * 1.01);
  EXPECT_GE(m.photon.mean, b.photon.mean * 0.97);
  EXPECT_LE(m.photon.mean, w.photon.mean * 1.03);
}

// A glass sphere of index 1.0 is no surface at all: the room renders as without it (within
// noise: light behind it arrives by BSDF sampling and caustic photons instead of shadow rays).
// Index 3.0 (total internal reflection over most of the inside) renders finite.
RoomSetup RoomWithGlass(float ior) {
  RoomSetup r = SnappedRoom();
  const uint32_t glass =
      AddMaterial(r.scene, Material{.name = "glass", .specular_transmittance = Rgb(1.0f), .ior = ior});
  testing::AddSphere(r.scene, Vec3(0.375f, 0.5f, -0.25f), 0.375f, 3, glass, /*inward=*/false);
  return r;
}

TEST(HardCasesGlass, IndexOneVanishes) {
  const RoomSetup room = SnappedRoom();
  const RoomSetup glass = RoomWithGlass(1.0f);
  const BothMeans a = RenderBoth(room.scene, room.camera, 256, 16, 100000);
  const BothMeans b = RenderBoth(glass.scene, glass.camera, 256, 16, 100000);
  EXPECT_NEAR(b.path.mean, a.path.mean, 0.02 * a.path.mean);
  EXPECT_NEAR(b.photon.mean, a.photon.mean, 0.04 * a.photon.mean);
}

TEST(HardCasesGlass, IndexThreeIsFinite) {
  const RoomSetup glass = RoomWithGlass(3.0f);
  const BothMeans b = RenderBoth(glass.scene, glass.camera);
  EXPECT_GT(b.path.mean, 0.05);
  EXPECT_GT(b.photon.mean, 0.05);
}

// A closed box of perfect mirrors (reflectance 1) with a light inside: no path is ever absorbed
// by a wall, so only the depth caps end them (path tracer 1024, photon tracer 64, photon-map
// camera paths 32); photons never land on a diffuse surface, so the maps are empty. Every camera
// path collects the light's emission at most once: 0 < mean ≤ Le.
TEST(HardCasesMirror, ClosedMirrorBoxTerminates) {
  RoomSetup r;
  SceneDescription& s = r.scene;
  const uint32_t mirror = AddMaterial(s, Material{.name = "mirror", .specular_reflectance = Rgb(1.0f)});
  const uint32_t lamp = AddMaterial(s, Material{.name = "lamp", .emission = Rgb(3.0f)});
  AddQuad(s, {-1, 0, -1}, {-1, 0, 1}, {1, 0, 1}, {1, 0, -1}, mirror);
  AddQuad(s, {-1, 2, -1}, {1, 2, -1}, {1, 2, 1}, {-1, 2, 1}, mirror);
  AddQuad(s, {-1, 0, -1}, {1, 0, -1}, {1, 2, -1}, {-1, 2, -1}, mirror);
  AddQuad(s, {-1, 0, 1}, {-1, 2, 1}, {1, 2, 1}, {1, 0, 1}, mirror);
  AddQuad(s, {-1, 0, -1}, {-1, 2, -1}, {-1, 2, 1}, {-1, 0, 1}, mirror);
  AddQuad(s, {1, 0, -1}, {1, 0, 1}, {1, 2, 1}, {1, 2, -1}, mirror);
  AddQuad(s, {-0.25f, 1.875f, -0.25f}, {0.25f, 1.875f, -0.25f}, {0.25f, 1.875f, 0.25f},
          {-0.25f, 1.875f, 0.25f}, lamp, 0);
  s.num_lights = 1;
  r.camera.eye = Vec3(0.1f, 1.0f, 0.7f);
  r.camera.look_at = Vec3(-0.2f, 0.8f, -1.0f);
  r.camera.width = r.camera.height = 16;
  const BothMeans m = RenderBoth(s, r.camera, 16, 4, 20000);
  EXPECT_GT(m.path.mean, 0.0);
  EXPECT_LE(m.path.mean, 3.0);
  EXPECT_GT(m.photon.mean, 0.0);
  EXPECT_LE(m.photon.mean, 3.0);
}

// A light enclosed in a closed black box: no photon is stored anywhere (every map is empty) and
// no light leaves the box, so the white room around it renders exactly black.
TEST(HardCasesEmptyMap, EnclosedLightRendersBlack) {
  RoomSetup r = SnappedRoom();
  SceneDescription& s = r.scene;
  const uint32_t black = AddMaterial(s, Material{.name = "black"});
  const float b = 0.5f, y0 = 1.75f, y1 = 1.9375f;  // box [-b, b]² around the light, y ∈ [y0, y1]
  AddQuad(s, {-b, y0, -b}, {b, y0, -b}, {b, y0, b}, {-b, y0, b}, black);
  AddQuad(s, {-b, y1, -b}, {-b, y1, b}, {b, y1, b}, {b, y1, -b}, black);
  AddQuad(s, {-b, y0, -b}, {-b, y1, -b}, {b, y1, -b}, {b, y0, -b}, black);
  AddQuad(s, {-b, y0, b}, {b, y0, b}, {b, y1, b}, {-b, y1, b}, black);
  AddQuad(s, {-b, y0, -b}, {-b, y0, b}, {-b, y1, b}, {-b, y1, -b}, black);
  AddQuad(s, {b, y0, -b}, {b, y1, -b}, {b, y1, b}, {b, y0, b}, black);
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  PhotonMapsOptions mo;
  mo.tracing.photons = 20000;
  const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
  EXPECT_EQ(maps.stats.stored_global + maps.stats.stored_caustic + maps.stats.stored_direct, 0u);
  const BothMeans m = RenderBoth(s, r.camera, 16, 4, 20000);
  EXPECT_EQ(m.path.mean, 0.0);
  EXPECT_EQ(m.photon.mean, 0.0);
}

// k larger than all the photons there are: every query returns the whole (small) map and
// divides by the disk of the farthest photon, which no longer describes the surface around x
// (a radius spanning the scene). In the furnace (closed sphere, Le = 1, albedo 0.8: L = 5; the
// emission 1 and the Monte Carlo direct light 0.8 are exact) the photons of the far half arrive
// from behind x's tangent plane and the BSDF gives them nothing: the indirect 3.2 comes out as
// about half, 3.4 in all, a bias of such queries, not a numerical failure. What must hold: a
// finite image, the exact parts kept (> 1.8) and nothing counted twice (< 5).
TEST(HardCasesFewPhotons, KLargerThanThePhotonsInRange) {
  const SceneDescription furnace = testing::FurnaceScene(0.8f);
  const RenderResult r =
      RenderMean(furnace, testing::FurnaceCamera(), IntegratorKind::kPhotonMap, 4, 2000, 100000);
  EXPECT_TRUE(r.finite);
  EXPECT_EQ(r.nonfinite, 0u);
  EXPECT_GT(r.mean, 1.8);
  EXPECT_LT(r.mean, 5.0);
  const RenderResult k50 =
      RenderMean(furnace, testing::FurnaceCamera(), IntegratorKind::kPhotonMap, 4, 20000, 50);
  EXPECT_NEAR(k50.mean, 5.0, 0.25) << "with k well below the photons, the same map gives L";
}

// Photon power near RGBE's limits (the 18-byte photon's shared exponent): the furnace with
// Le = 1e-35 (photon powers ~2e-38, at the bottom of RGBE's normal range) and Le = 1e30 renders
// Le times the Le = 1 image, with either integrator, to 1 % (rendered with float sums: the
// farm's fixed-point accumulator has its own range, tested below).
TEST(HardCasesRgbe, PhotonPowerNearTheLimitsScalesLinearly) {
  const CameraSpec cam = testing::FurnaceCamera();
  auto with_emission = [](float le) {
    SceneDescription s = testing::FurnaceScene(0.8f);
    s.materials[0].emission = Rgb(le);
    return s;
  };
  for (IntegratorKind kind : {IntegratorKind::kPath, IntegratorKind::kPhotonMap}) {
    const double one = RenderWorldMean(with_emission(1.0f), cam, kind, 16, 20000, 50).mean;
    for (float le : {1e-35f, 1e30f}) {
      const RenderResult r = RenderWorldMean(with_emission(le), cam, kind, 16, 20000, 50);
      EXPECT_TRUE(r.finite);
      EXPECT_NEAR(r.mean / double(le), one, 0.01 * one) << "Le " << le << " integrator " << int(kind);
    }
  }
}

// Irradiance at x (normal n) from a uniform Lambertian polygon of radiance Le, by Lambert's
// contour formula (as in path_tracer_test.cpp): E = Le · ½ |Σ_i Θ_i (n · Γ_i)|.
double PolygonIrradiance(const Vec3d& x, const Vec3d& n, const std::vector<Vec3d>& polygon, double le) {
  double sum = 0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Vec3d a = Normalize(polygon[i] - x);
    const Vec3d b = Normalize(polygon[(i + 1) % polygon.size()] - x);
    const double theta = std::acos(std::clamp(Dot(a, b), -1.0, 1.0));
    sum += theta * Dot(n, Normalize(Cross(a, b)));
  }
  return le * 0.5 * std::fabs(sum);
}

// A 1 mm² light of radiance 1e6 beside a 1 m² light of radiance 1e-3 (selection probabilities
// 1 : 1e-3) over a grey floor, seen from above: every pixel is ρ/π · (E_tiny + E_dim), the
// irradiances by Lambert's formula at the pixel's floor point. Both integrators within 2 %.
TEST(HardCasesLights, TinyBrightLightBesideADimOne) {
  SceneDescription s;
  const float rho = 0.5f;
  const uint32_t floor = AddMaterial(s, Material{.name = "floor", .diffuse_reflectance = Rgb(rho)});
  const uint32_t bright = AddMaterial(s, Material{.name = "bright", .emission = Rgb(1e6f)});
  const uint32_t dim = AddMaterial(s, Material{.name = "dim", .emission = Rgb(1e-3f)});
  AddQuad(s, {-5, 0, -5}, {-5, 0, 5}, {5, 0, 5}, {5, 0, -5}, floor);
  const float h = 0.0005f;  // the tiny light: 1 mm square at y = 1, facing down
  const std::vector<Vec3> tiny = {{-h, 1, -h}, {h, 1, -h}, {h, 1, h}, {-h, 1, h}};
  const std::vector<Vec3> wide = {{0.3f, 1, -0.5f}, {1.3f, 1, -0.5f}, {1.3f, 1, 0.5f}, {0.3f, 1, 0.5f}};
  AddQuad(s, tiny[0], tiny[1], tiny[2], tiny[3], bright, 0);
  AddQuad(s, wide[0], wide[1], wide[2], wide[3], dim, 1);
  s.num_lights = 2;
  CameraSpec cam;
  cam.eye = Vec3(0.4f, 0.9f, 0.0f);
  cam.look_at = Vec3(0.4f, 0.0f, 0.0f);
  cam.up = Vec3(0, 0, -1);
  cam.vfov_degrees = 60.0f;
  cam.width = cam.height = 12;
  // The expected mean: the pixel box filter's average, by 8 x 8 rays per pixel to the floor.
  const Camera camera(cam);
  std::vector<Vec3d> tiny_d, wide_d;
  for (const Vec3& p : tiny) tiny_d.push_back(Vec3d(p));
  for (const Vec3& p : wide) wide_d.push_back(Vec3d(p));
  double expected = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      for (int j = 0; j < 64; ++j) {
        const Ray ray = camera.GenerateRay(x, y, (float(j % 8) + 0.5f) / 8.0f, (float(j / 8) + 0.5f) / 8.0f);
        const Vec3d o(ray.origin), d(ray.direction);
        const Vec3d p = o + d * (-o.y / d.y);
        const Vec3d n(0, 1, 0);
        expected += PolygonIrradiance(p, n, tiny_d, 1e6) + PolygonIrradiance(p, n, wide_d, 1e-3);
      }
  expected *= rho / std::numbers::pi / double(cam.width * cam.height * 64);
  const BothMeans m = RenderBoth(s, cam, 64, 16, 20000);
  EXPECT_NEAR(m.path.mean, expected, 0.02 * expected);
  EXPECT_NEAR(m.photon.mean, expected, 0.02 * expected);
}

// The farm merges pixel sums in 64-bit fixed point (2^-32 units, docs/design.md G1), so its
// range is bounded: a task whose sums exceed 2^30 is refused with a clear message (the furnace
// at Le = 1e30), never merged as Inf or wrapped around.
TEST(HardCasesRgbe, RadianceBeyondTheAccumulatorIsAClearError) {
  SceneDescription s = testing::FurnaceScene(0.8f);
  s.materials[0].emission = Rgb(1e30f);
  const SceneRuntime runtime(s);
  JobRenderSettings settings;
  settings.photons = 2000;
  const PlanSpec plan{.kind = PlanKind::kMultipleMaps, .maps = 1, .samples_per_pixel = 1};
  try {
    RenderPlanLocally(runtime, testing::FurnaceCamera(), settings, plan, 1, 0);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("exceeds the accumulator range"), std::string::npos) << e.what();
  }
}

// The photon maps in world coordinates at 1e6 (a map built outside SceneRuntime's local frame):
// photons on the walls of a 2 m room, their float positions on the 6.25 cm lattice there, many
// at equal distances. Every structure (kd-tree with both split rules, grid, bucket kd-tree)
// finds exactly the brute-force k nearest (same distance multiset), bounded and unbounded:
// kd-tree boxes and grid cells are exact at that magnitude.
TEST(HardCasesPhotonMaps, QueriesAtOneMillionMatchBruteForce) {
  Rng rng(15, 15);
  std::vector<Photon> photons;
  const Vec3 far(1e6f, -1e6f, 1e6f);
  for (int i = 0; i < 20000; ++i) {
    Vec3 p{2.0f * rng.Uniform(), 2.0f * rng.Uniform(), 2.0f * rng.Uniform()};
    const uint32_t face = rng.UniformInt(6);
    p[int(face / 2)] = 2.0f * float(face % 2);
    photons.push_back(Photon::Make(far + p, {0, 1, 0}, Rgb(0.5f)));
  }
  struct Kind {
    PhotonMapKind kind;
    KdSplitRule rule;
    KdCulling culling;
  };
  for (const Kind kind :
       {Kind{PhotonMapKind::kKdTree, KdSplitRule::kLevelCycle, KdCulling::kPlaneDistance},
        Kind{PhotonMapKind::kKdTree, KdSplitRule::kWidestExtent, KdCulling::kCellDistance},
        Kind{PhotonMapKind::kGrid, KdSplitRule::kWidestExtent, KdCulling::kCellDistance},
        Kind{PhotonMapKind::kBucketKdTree, KdSplitRule::kWidestExtent, KdCulling::kCellDistance}}) {
    PhotonMapOptions options;
    options.kd_split_rule = kind.rule;
    options.kd_culling = kind.culling;
    std::unique_ptr<PhotonMap> map = MakePhotonMap(kind.kind, options);
    map->AddPhotons(photons);
    map->PrepareForQuery();
    NearestPhotons nearest;
    for (int q = 0; q < 200; ++q) {
      const Vec3 x =
          far + Vec3(2.2f * rng.Uniform() - 0.1f, 2.2f * rng.Uniform() - 0.1f, 2.2f * rng.Uniform() - 0.1f);
      for (int k : {1, 50, 500}) {
        for (float radius : {std::numeric_limits<float>::infinity(), 0.2f}) {
          map->Query(x, k, radius, nearest);
          const auto expected = BruteForceNearest(map->photons(), x, k, radius);
          ASSERT_EQ(nearest.size(), expected.size()) << "kind " << int(kind.kind) << " query " << q;
          nearest.Sort();
          for (size_t j = 0; j < expected.size(); ++j)
            ASSERT_EQ(nearest[j].distance2, expected[j].distance2)
                << "kind " << int(kind.kind) << " query " << q;
        }
      }
    }
  }
}

// A light seen only through a mirror: a 1 m² light at y = 1 faces up to a mirror ceiling at
// y = 2; a small grey patch on the floor, off to the side, sees the light's back (black) and
// its mirror image, the light reflected to y = 3 facing down. Every pixel is ρ/π · E from that
// image (Lambert's formula); the patch's own reflection in the mirror adds < 0.5 %. The path
// tracer reaches the light only by BSDF sampling through the mirror (shadow rays are blocked),
// the photon map only through caustic photons. Path tracer: 262k paths, ~1 % of which reach the
// light; four more seeds gave 0.0711–0.0725 for 0.0714 (std 0.8 %): 3 % is a > 3σ bound.
TEST(HardCasesMirror, LightSeenOnlyThroughAMirror) {
  SceneDescription s;
  const float rho = 0.8f;
  const uint32_t patch = AddMaterial(s, Material{.name = "patch", .diffuse_reflectance = Rgb(rho)});
  const uint32_t mirror = AddMaterial(s, Material{.name = "mirror", .specular_reflectance = Rgb(1.0f)});
  const uint32_t lamp = AddMaterial(s, Material{.name = "lamp", .emission = Rgb(10.0f)});
  AddQuad(s, {2.75f, 0, -0.25f}, {2.75f, 0, 0.25f}, {3.25f, 0, 0.25f}, {3.25f, 0, -0.25f}, patch);
  AddQuad(s, {-10, 2, -10}, {10, 2, -10}, {10, 2, 10}, {-10, 2, 10}, mirror);
  AddQuad(s, {-0.5f, 1, -0.5f}, {-0.5f, 1, 0.5f}, {0.5f, 1, 0.5f}, {0.5f, 1, -0.5f}, lamp, 0);
  s.num_lights = 1;
  CameraSpec cam;
  cam.eye = Vec3(3.0f, 1.0f, 0.0f);
  cam.look_at = Vec3(3.0f, 0.0f, 0.0f);
  cam.up = Vec3(0, 0, -1);
  cam.vfov_degrees = 20.0f;  // sees only the patch
  cam.width = cam.height = 8;
  const std::vector<Vec3d> image = {{-0.5, 3, -0.5}, {0.5, 3, -0.5}, {0.5, 3, 0.5}, {-0.5, 3, 0.5}};
  const Camera camera(cam);
  double expected = 0;
  for (int y = 0; y < cam.height; ++y)
    for (int x = 0; x < cam.width; ++x)
      for (int j = 0; j < 16; ++j) {
        const Ray ray = camera.GenerateRay(x, y, (float(j % 4) + 0.5f) / 4.0f, (float(j / 4) + 0.5f) / 4.0f);
        const Vec3d o(ray.origin), d(ray.direction);
        expected += PolygonIrradiance(o + d * (-o.y / d.y), Vec3d(0, 1, 0), image, 10.0);
      }
  expected *= rho / std::numbers::pi / double(cam.width * cam.height * 16);
  const BothMeans m = RenderBoth(s, cam, 4096, 16, 400000, 50);
  EXPECT_NEAR(m.path.mean, expected, 0.03 * expected);
  // One map of ~900 caustic photons on the patch: five map seeds gave 0.0676–0.0761, mean
  // 0.0716 for 0.0714 (unbiased), std 4 %: 12 % is a 3σ bound.
  EXPECT_NEAR(m.photon.mean, expected, 0.12 * expected);
}

// Grazing rays on shading normals: a smooth (vertex-normal) sphere, coarsely tessellated so
// that shading and geometric normals differ by up to ~20°, seen edge-on under a light. Rays
// whose direction is above one normal and below the other must not produce NaN, negative or
// exploding values. In this closed room of albedos ≤ 0.9 (and ρd + ρs = 0.9) no radiance
// exceeds the lamp's Le = 12, so no pixel (32 samples) may either.
TEST(HardCasesShadingNormals, GrazingRaysStayFiniteAndBounded) {
  RoomSetup r = SnappedRoom();
  const uint32_t white = AddMaterial(r.scene, Material{.name = "smooth", .diffuse_reflectance = Rgb(0.9f)});
  const uint32_t glossy = AddMaterial(r.scene, Material{.name = "glossy",
                                                        .diffuse_reflectance = Rgb(0.3f),
                                                        .specular_reflectance = Rgb(0.6f),
                                                        .specular_roughness = 0.05f});
  testing::AddSphere(r.scene, Vec3(0.4f, 0.4f, -0.3f), 0.35f, 1, white, /*inward=*/false);
  testing::AddSphere(r.scene, Vec3(-0.2f, 1.1f, -0.5f), 0.3f, 1, glossy, /*inward=*/false);
  const SceneRuntime runtime(r.scene);
  for (IntegratorKind kind : {IntegratorKind::kPath, IntegratorKind::kPhotonMap}) {
    JobRenderSettings settings;
    settings.integrator = kind;
    settings.photons = 50000;
    settings.k = 50;
    const PlanSpec plan{.kind = PlanKind::kMultipleMaps, .maps = 1, .samples_per_pixel = 32};
    const Image img = RenderPlanLocally(runtime, r.camera, settings, plan, 1, 0);
    for (size_t i = 0; i < img.size(); ++i) {
      ASSERT_TRUE(img[i].IsFinite()) << i;
      ASSERT_GE(std::min({img[i].r, img[i].g, img[i].b}), 0.0f) << i;
      ASSERT_LE(img[i].Max(), 12.0f) << i << " (integrator " << int(kind) << ")";
    }
  }
}

}  // namespace
}  // namespace pf
