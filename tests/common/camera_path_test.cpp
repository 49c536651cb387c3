// A camera path (common/scene/camera_path.h; a manifest's "camera_path", docs/scene-manifest.md):
// keys are met exactly, frames between them are linear, a key's missing up and field of view are the
// base camera's, frames outside the path and degenerate views are input errors, and every malformed
// manifest key is named.
#include "common/scene/camera_path.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/core/error.h"
#include "common/scene/manifest.h"
#include "common/scene/scene_loader.h"
#include "tests/util/input_error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using ::testing::HasSubstr;

CameraPath Path() {
  CameraPath p;
  p.keys.push_back({.frame = 1, .eye = Vec3d(0, 1, 4), .look_at = Vec3d(0, 1, 0)});
  p.keys.push_back({.frame = 11, .eye = Vec3d(2, 1, 2), .look_at = Vec3d(0, 0, 0), .vfov_degrees = 60.0f});
  p.keys.push_back(
      {.frame = 12, .eye = Vec3d(0.1, 0.2, 0.3), .look_at = Vec3d(0, 0, 0), .up = Vec3(0, 0, 1)});
  return p;
}

CameraSpec Base() {
  CameraSpec c;
  c.name = "main";
  c.vfov_degrees = 40.0f;
  c.width = 32;
  c.height = 24;
  return c;
}

TEST(CameraPath, KeysAreMetExactlyAndFramesBetweenAreLinear) {
  const CameraPath path = Path();
  const CameraSpec key = CameraAtFrame(path, Base(), 12);
  EXPECT_EQ(key.eye, Vec3d(0.1, 0.2, 0.3)) << "bit for bit, not a rounding of an interpolation";
  EXPECT_EQ(key.up, Vec3(0, 0, 1));
  EXPECT_EQ(key.vfov_degrees, 40.0f) << "the base camera's field of view";
  EXPECT_EQ(key.width, 32);
  EXPECT_EQ(key.height, 24);
  EXPECT_EQ(key.name, "main@12");

  const CameraSpec mid = CameraAtFrame(path, Base(), 6);  // halfway from frame 1 to 11
  EXPECT_NEAR(mid.eye.x, 1.0, 1e-12);
  EXPECT_NEAR(mid.eye.z, 3.0, 1e-12);
  EXPECT_NEAR(mid.look_at.y, 0.5, 1e-12);
  EXPECT_NEAR(mid.vfov_degrees, 50.0f, 1e-5f);
  EXPECT_EQ(CamerasOfFrames(path, Base(), 1, 12).size(), 12u);
}

TEST(CameraPath, FramesOutsideThePathAndDegenerateViewsAreErrors) {
  EXPECT_THAT(testing::InputErrorOf([] { CameraAtFrame(Path(), Base(), 0); }),
              HasSubstr("frame 0: outside the camera path's frames 1-12"));
  EXPECT_THAT(testing::InputErrorOf([] { CameraAtFrame(Path(), Base(), 13); }), HasSubstr("outside"));
  CameraPath looking_up;
  looking_up.keys.push_back({.frame = 0, .eye = Vec3d(0, 0, 0), .look_at = Vec3d(0, 5, 0)});
  EXPECT_THAT(testing::InputErrorOf([&] { CameraAtFrame(looking_up, Base(), 0); }),
              HasSubstr("up is parallel to the view direction"));
}

class CameraPathManifest : public test_util::TempDirTest {};

TEST_F(CameraPathManifest, IsParsedScaledAndEachMalformedKeyIsNamed) {
  const std::string box = R"("geometry": "box.obj", "scale": 2)";
  tmp_.Write("box.mtl", "newmtl lamp\nKe 1 1 1\n");
  tmp_.Write("box.obj", "mtllib box.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl lamp\nf 1 2 3\n");
  const auto path = tmp_.Write("a.json", "{" + box + R"(, "camera_path": [
      {"frame": 3, "eye": [0, 0, 5], "look_at": [0, 0, 0]},
      {"frame": 9, "eye": [1, 0, 5], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 30}]})");
  const SceneDescription scene = LoadScene(path);
  ASSERT_EQ(scene.camera_path.keys.size(), 2u);
  EXPECT_EQ(scene.camera_path.first_frame(), 3);
  EXPECT_EQ(scene.camera_path.last_frame(), 9);
  EXPECT_EQ(scene.camera_path.keys[1].eye, Vec3d(2, 0, 10)) << "scaled like camera points";
  EXPECT_EQ(scene.camera_path.keys[1].vfov_degrees, 30.0f);

  struct Bad {
    const char* path;
    const char* message;
  };
  for (
      const Bad& bad : {
          Bad{R"([])", "key 'camera_path': expected a non-empty array"},
          Bad{R"([{"eye": [0,0,1], "look_at": [0,0,0]}])", "key 'camera_path[0].frame': expected an integer"},
          Bad{R"([{"frame": -1, "eye": [0,0,1], "look_at": [0,0,0]}])", "key 'camera_path[0].frame'"},
          Bad{R"([{"frame": 2, "eye": [0,0,1], "look_at": [0,0,0]}, {"frame": 2, "eye": [0,0,1], "look_at": [0,0,0]}])",
              "key 'camera_path[1].frame': expected frames in strictly increasing order"},
          Bad{R"([{"frame": 1, "look_at": [0,0,0]}])", "key 'camera_path[0].eye': missing"},
          Bad{R"([{"frame": 1, "eye": [0,0,1], "look_at": [0,0]}])",
              "key 'camera_path[0].look_at': expected 3"},
          Bad{R"([{"frame": 1, "eye": [0,0,1], "look_at": [0,0,0], "fov": 180}])",
              "key 'camera_path[0].fov'"},
      }) {
    const auto p = tmp_.Write("bad.json", "{" + box + R"(, "camera_path": )" + bad.path + "}");
    EXPECT_THAT(testing::InputErrorOf([&] { ParseManifest(test_util::ReadFileBytes(p), p); }),
                HasSubstr(bad.message))
        << bad.path;
  }
}

}  // namespace
}  // namespace pf
