// A glTF camera's animation as the scene's camera path (common/scene/gltf_camera_path.h; docs/gltf.md
// "Camera animation"): keys at frame 1 + round(24 t), the node's world transform at each (under its
// parent), LINEAR rotations slerped, STEP held, malformed channels named, and a manifest's own
// camera_path preferred.
#include "common/scene/gltf_camera_path.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "common/scene/camera_path.h"
#include "common/scene/gltf_loader.h"
#include "common/scene/scene_loader.h"
#include "tests/common/gltf_test_util.h"
#include "tests/util/input_error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using gltf_test::GltfBuilder;
using ::testing::HasSubstr;

constexpr const char* kMeshAndLamp =
    R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"material":0}]}],
       "materials":[{"name":"lamp","emissiveFactor":[1,1,1]}],
       "cameras":[{"type":"perspective","perspective":{"yfov":0.6,"znear":0.1}}])";

void ExpectNear(const Vec3d& got, const Vec3d& want, double tol = 1e-6) {
  EXPECT_NEAR(got.x, want.x, tol);
  EXPECT_NEAR(got.y, want.y, tol);
  EXPECT_NEAR(got.z, want.z, tol);
}

// A triangle, a camera node (1) under a parent (2) lifted 1 m, and `animation` on node 1: times 0,
// 1 and 2 s; the translation moves +x 2 m a second, the rotation turns 90° about +y in the first
// second and stays.
std::string Scene(const std::string& interpolation, const std::string& more_channels = "") {
  GltfBuilder b;
  b.AddVec3({0, 0, -5, 1, 0, -5, 0, 1, -5});
  b.AddIndices16({0, 1, 2});
  const int times = b.AddScalars({0.0f, 1.0f, 2.0f});
  const int moves = b.AddVec3({0, 0, 0, 2, 0, 0, 4, 0, 0});
  const float h = float(std::sqrt(0.5));
  const int turns = b.AddVec4({0, 0, 0, 1, 0, h, 0, h, 0, h, 0, h});
  const std::string t = std::to_string(times);
  return b.Json(std::string(R"("scenes":[{"nodes":[0,2]}],"nodes":[{"mesh":0},{"camera":0},
      {"translation":[0,1,0],"children":[1]}],
      "animations":[{"samplers":[{"input":)") +
                t + R"(,"output":)" + std::to_string(moves) + R"(,"interpolation":")" + interpolation +
                R"("},{"input":)" + t + R"(,"output":)" + std::to_string(turns) + R"(,"interpolation":")" +
                interpolation + R"("}],
      "channels":[{"sampler":0,"target":{"node":1,"path":"translation"}},
                  {"sampler":1,"target":{"node":1,"path":"rotation"}})" +
                more_channels + R"(]}],)" + kMeshAndLamp);
}

TEST(GltfCameraPath, KeysAreTheNodesWorldTransformAtFrameOnePlus24T) {
  test_util::TempDir dir("pf_gltf_camera_path");
  const SceneDescription s = LoadGltf(dir.Write("a.gltf", Scene("LINEAR")));
  const CameraPath& path = s.camera_path;
  // A key per frame, 1 (t = 0) to 49 (t = 2 s).
  ASSERT_EQ(path.keys.size(), 49u);
  for (size_t i = 0; i < path.keys.size(); ++i) EXPECT_EQ(path.keys[i].frame, int(i) + 1);
  ExpectNear(path.keys[0].eye, {0, 1, 0});  // the parent's lift
  ExpectNear(path.keys[0].look_at - path.keys[0].eye, {0, 0, -1});
  ExpectNear(path.keys[24].eye, {2, 1, 0});
  ExpectNear(path.keys[48].eye, {4, 1, 0});
  ExpectNear(path.keys[48].look_at - path.keys[48].eye, {-1, 0, 0});  // turned 90° about +y
  ASSERT_TRUE(path.keys[24].up.has_value());
  ExpectNear(Vec3d(*path.keys[24].up), {0, 1, 0});
  EXPECT_THAT(::testing::PrintToString(s.warnings),
              HasSubstr("animations are not applied, except the camera's"));

  // Frame 13 (t = 0.5 s) halfway along the first second: moved 1 m, turned 45° (slerped).
  const CameraSpec mid = CameraAtFrame(path, s.cameras.at(0), 13);
  ExpectNear(mid.eye, {1, 1, 0});
  ExpectNear(mid.look_at - mid.eye, {-std::sqrt(0.5), 0, -std::sqrt(0.5)});
}

TEST(GltfCameraPath, SlerpHalfwayAndStepHolds) {
  test_util::TempDir dir("pf_gltf_camera_path");
  // A rotation keyed at 0 and 1 s (and a translation keyed at 0, 0.5 and 1 s): frame 13 takes the
  // rotation halfway — slerped (LINEAR) or held (STEP) — and STEP still holds at frame 24, a frame
  // before the next key.
  GltfBuilder b;
  b.AddVec3({0, 0, -5, 1, 0, -5, 0, 1, -5});
  b.AddIndices16({0, 1, 2});
  const int rot_times = b.AddScalars({0.0f, 1.0f});
  const float h = float(std::sqrt(0.5));
  const int turns = b.AddVec4({0, 0, 0, 1, 0, h, 0, h});
  const int move_times = b.AddScalars({0.0f, 0.5f, 1.0f});
  const int moves = b.AddVec3({0, 0, 0, 1, 0, 0, 2, 0, 0});
  for (const char* interpolation : {"LINEAR", "STEP"}) {
    SCOPED_TRACE(interpolation);
    const std::string json =
        b.Json(std::string(R"("scenes":[{"nodes":[0,1]}],"nodes":[{"mesh":0},{"camera":0}],
      "animations":[{"samplers":[{"input":)") +
               std::to_string(rot_times) + R"(,"output":)" + std::to_string(turns) + R"(,"interpolation":")" +
               interpolation + R"("},{"input":)" + std::to_string(move_times) + R"(,"output":)" +
               std::to_string(moves) +
               R"(}],"channels":[{"sampler":0,"target":{"node":1,"path":"rotation"}},
                          {"sampler":1,"target":{"node":1,"path":"translation"}}]}],)" +
               kMeshAndLamp);
    const CameraPath path = LoadGltf(dir.Write("b.gltf", json)).camera_path;
    ASSERT_EQ(path.keys.size(), 25u);
    EXPECT_EQ(path.keys[12].frame, 13);  // 1 + 24 · 0.5
    const Vec3d forward = path.keys[12].look_at - path.keys[12].eye;
    const Vec3d before_key = path.keys[23].look_at - path.keys[23].eye;
    if (std::string(interpolation) == "LINEAR") {
      // 45° about +y: the slerp, not a normalised lerp of the matrices.
      ExpectNear(forward, {-std::sqrt(0.5), 0, -std::sqrt(0.5)});
    } else {
      ExpectNear(forward, {0, 0, -1});
      ExpectNear(before_key, {0, 0, -1});
    }
  }
}

TEST(GltfCameraPath, MalformedChannelsAreNamed) {
  test_util::TempDir dir("pf_gltf_camera_path");
  // A warning: the scene loads and renders still frames, without a path.
  const SceneDescription bezier = LoadGltf(dir.Write("c.gltf", Scene("BEZIER")));
  EXPECT_TRUE(bezier.camera_path.keys.empty());
  EXPECT_THAT(
      ::testing::PrintToString(bezier.warnings),
      HasSubstr(
          "animations[0].channels[0]: unknown interpolation 'BEZIER' (the camera's animation is not used)"));
  const std::string scaled = Scene("LINEAR", R"(,{"sampler":0,"target":{"node":1,"path":"scale"}})");
  EXPECT_THAT(::testing::PrintToString(LoadGltf(dir.Write("d.gltf", scaled)).warnings),
              HasSubstr("animations[0].channels[2]: the camera's scale is not animated"));
}

TEST(GltfCameraPath, AManifestsCameraPathIsPreferred) {
  test_util::TempDir dir("pf_gltf_camera_path");
  dir.Write("a.gltf", Scene("LINEAR"));
  EXPECT_EQ(LoadScene(dir.Write("with.json", R"({"geometry": "a.gltf", "camera_path": [
      {"frame": 5, "eye": [0, 0, 3], "look_at": [0, 0, 0]}]})"))
                .camera_path.first_frame(),
            5);
  EXPECT_EQ(LoadScene(dir.Write("without.json", R"({"geometry": "a.gltf"})")).camera_path.last_frame(), 49);
  // Cameras of the manifest's own: the glTF camera's motion is not theirs.
  EXPECT_TRUE(LoadScene(dir.Write("cameras.json", R"({"geometry": "a.gltf", "cameras": [
      {"eye": [0, 0, 3], "look_at": [0, 0, 0]}]})"))
                  .camera_path.keys.empty());
}

}  // namespace
}  // namespace pf
