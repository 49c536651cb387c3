// A manifest's "lights" (docs/scene-manifest.md; common/scene/manifest.cpp, punctual_light.h) and
// the rule that a scene without any light is an input error (scene_loader.cpp, RequireLight):
// every key parsed, every malformed key named, ids after the emitting primitives, "scale", the
// bundle (its hash covers the lights; a worker loads the same ones), and the no-light messages.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "common/core/error.h"
#include "common/scene/manifest.h"
#include "common/scene/scene_bundle.h"
#include "common/scene/scene_loader.h"
#include "tests/util/input_error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

const fs::path kScenes = fs::path(PF_SOURCE_DIR) / "scenes";

class ManifestLightsTest : public test_util::TempDirTest {
 protected:
  fs::path Write(const std::string& name, const std::string& text) const { return tmp_.Write(name, text); }

  // A one-triangle OBJ whose material neither emits nor has Ka.
  std::string DarkObj() const {
    Write("dark.mtl", "newmtl grey\nKd 0.5 0.5 0.5\n");
    Write("dark.obj", "mtllib dark.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl grey\nf 1 2 3\n");
    return "dark.obj";
  }
};

TEST_F(ManifestLightsTest, ParsesEveryKeyAndTheDefaults) {
  const fs::path p = Write("m.json", R"({"geometry": "a.obj", "lights": [
      {"type": "point", "name": "bulb", "position": [1, 2, 3], "color": [1, 0.5, 0.25], "intensity": 8},
      {"type": "spot", "position": [0, 3, 0], "direction": [0, -2, 0], "intensity": 2,
       "inner_cone_deg": 10, "outer_cone_deg": 30},
      {"type": "directional", "direction": [0, 0, -5], "color": 3},
      {"type": "spot", "position": [0, 0, 0], "direction": [1, 0, 0]}]})");
  const SceneManifest m = LoadManifest(p);
  ASSERT_EQ(m.lights.size(), 4u);
  EXPECT_TRUE(m.warnings.empty());
  const PunctualLight& point = m.lights[0];
  EXPECT_EQ(point.kind, PunctualLight::Kind::kPoint);
  EXPECT_EQ(point.name, "bulb");
  EXPECT_EQ(point.position, Vec3d(1, 2, 3));
  EXPECT_EQ(point.intensity, Rgb(8, 4, 2));  // color × intensity
  const PunctualLight& spot = m.lights[1];
  EXPECT_EQ(spot.kind, PunctualLight::Kind::kSpot);
  EXPECT_EQ(spot.direction, Vec3(0, -1, 0));  // normalised
  EXPECT_EQ(spot.intensity, Rgb(2.0f));
  EXPECT_EQ(spot.inner_cone_deg, 10.0f);
  EXPECT_EQ(spot.outer_cone_deg, 30.0f);
  const PunctualLight& sun = m.lights[2];
  EXPECT_EQ(sun.kind, PunctualLight::Kind::kDirectional);
  EXPECT_EQ(sun.direction, Vec3(0, 0, -1));
  EXPECT_EQ(sun.intensity, Rgb(3.0f));
  // glTF's defaults: intensity 1, white, cones 0° and 45°.
  EXPECT_EQ(m.lights[3].intensity, Rgb(1.0f));
  EXPECT_EQ(m.lights[3].inner_cone_deg, 0.0f);
  EXPECT_EQ(m.lights[3].outer_cone_deg, 45.0f);
}

TEST_F(ManifestLightsTest, KeysAnotherTypeDoesNotUseAreWarnings) {
  const fs::path p = Write("w.json", R"({"geometry": "a.obj", "lights": [
      {"type": "point", "position": [0, 1, 0], "direction": [0, -1, 0], "outer_cone_deg": 20, "size": 2}]})");
  const SceneManifest m = LoadManifest(p);
  ASSERT_EQ(m.warnings.size(), 3u);
  EXPECT_THAT(m.warnings[0], HasSubstr("key 'lights[0].size' is not part of the manifest format"));
  EXPECT_THAT(m.warnings[1], HasSubstr("key 'lights[0].direction' is not used by a point light"));
  EXPECT_THAT(m.warnings[2], HasSubstr("key 'lights[0].outer_cone_deg' is not used by a point light"));
}

TEST_F(ManifestLightsTest, EachMalformedKeyIsNamed) {
  const std::string point = R"({"type": "point", "position": [0, 1, 0]})";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"("lights": {})", "key 'lights': expected an array"},
      {R"("lights": [3])", "key 'lights[0]': expected an object"},
      {R"("lights": [{"position": [0, 1, 0]}])", "key 'lights[0].type': missing"},
      {R"("lights": [{"type": "area"}])",
       "key 'lights[0].type': expected \"point\", \"spot\" or \"directional\""},
      {R"("lights": [{"type": "point"}])", "key 'lights[0].position': missing"},
      {R"("lights": [{"type": "point", "position": [0, 1]}])",
       "key 'lights[0].position': expected 3 numbers"},
      {R"("lights": [{"type": "point", "position": [0, 1, 1e39]}])", "key 'lights[0].position'"},
      {R"("lights": [{"type": "directional"}])", "key 'lights[0].direction': missing"},
      {R"("lights": [{"type": "directional", "direction": [0, 0, 0]}])",
       "key 'lights[0].direction': expected a non-zero vector"},
      {R"("lights": [)" + point + R"(, {"type": "spot", "position": [0, 1, 0]}])",
       "key 'lights[1].direction'"},
      {R"("lights": [{"type": "point", "position": [0, 1, 0], "intensity": -1}])",
       "key 'lights[0].intensity': expected a finite number >= 0"},
      {R"("lights": [{"type": "point", "position": [0, 1, 0], "intensity": 0}])",
       "key 'lights[0].intensity': color x intensity must be finite and not black"},
      {R"("lights": [{"type": "point", "position": [0, 1, 0], "color": [0, 0, 0]}])",
       "key 'lights[0].color'"},
      {R"("lights": [{"type": "point", "position": [0, 1, 0], "color": [1, -1, 0]}])",
       "key 'lights[0].color'"},
      {R"("lights": [{"type": "point", "position": [0, 1, 0], "name": 4}])", "key 'lights[0].name'"},
      {R"("lights": [)" + point +
           R"(, {"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0], "outer_cone_deg": 95}])",
       "key 'lights[1].outer_cone_deg': expected degrees in [0, 90]"},
      {R"("lights": [{"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0], "inner_cone_deg": "x"}])",
       "key 'lights[0].inner_cone_deg': expected a number"},
      {R"("lights": [{"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0], "inner_cone_deg": 30,
           "outer_cone_deg": 30}])",
       "key 'lights[0].outer_cone_deg': expected an angle at least 0.1"},
      // So narrow that cos θi and cos θo are one float: the spot would emit nothing.
      {R"("lights": [{"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0], "outer_cone_deg": 0.01}])",
       "key 'lights[0].outer_cone_deg': expected an angle at least 0.1"},
      // 4π·I would overflow a float: the light would be dropped and the scene render black.
      {R"("lights": [{"type": "point", "position": [0, 1, 0], "intensity": 3e37}])",
       "key 'lights[0].intensity': color x intensity exceeds"},
  };
  for (const auto& [lights, expected] : cases) {
    const fs::path p = Write("bad.json", R"({"geometry": "a.obj", )" + lights + "}");
    const std::string msg = testing::InputErrorOf([&] { LoadManifest(p); });
    EXPECT_THAT(msg, HasSubstr(expected)) << lights;
    EXPECT_EQ(msg.rfind(p.string() + ": ", 0), 0u) << "message must start with the file: " << msg;
  }
}

// Manifest lights are numbered after the geometry's emitting primitives, one id each; "scale"
// moves their positions like camera points.
TEST_F(ManifestLightsTest, LightsGetIdsAfterTheEmittersAndScaleWithTheScene) {
  for (const char* f : {"CornellBox-Original.obj", "CornellBox-Original.mtl"})
    fs::copy_file(kScenes / "cornell-box" / f, dir_ / f);
  const fs::path p = Write("lit.json", R"({"geometry": "CornellBox-Original.obj", "scale": 2, "lights": [
      {"type": "point", "position": [0, 5, 0]}, {"type": "directional", "direction": [0, -1, 0]}]})");
  const SceneDescription s = LoadScene(p);
  ASSERT_EQ(s.punctual_lights.size(), 2u);
  EXPECT_EQ(s.num_lights, 3u) << "the box's lamp, then the two manifest lights";
  EXPECT_EQ(s.punctual_lights[0].light, 1u);
  EXPECT_EQ(s.punctual_lights[1].light, 2u);
  EXPECT_EQ(s.punctual_lights[0].position, Vec3d(0, 10, 0));
  EXPECT_EQ(s.punctual_lights[1].direction, Vec3(0, -1, 0));
  // The box (1.99 m) fits at 1e38, the light 5 m up does not.
  EXPECT_THAT(testing::InputErrorOf([&] { LoadScene(p, 1e38); }),
              HasSubstr("lit.json: scale override: 1e+38 makes lights[0].position overflow a 32-bit float"));
}

// The lights live in the manifest, so the bundle's hash covers them, and a worker loading the
// bundle gets the lights the client loaded.
TEST_F(ManifestLightsTest, TheBundleHashCoversTheLightsAndTheBundleLoadsThem) {
  const std::string obj = DarkObj();
  const auto manifest = [&](const std::string& intensity) {
    return Write("scene.json", R"({"geometry": ")" + obj + R"(", "lights": [
        {"type": "spot", "position": [0.2, 0.2, 1], "direction": [0, 0, -1], "intensity": )" +
                                   intensity + "}]}");
  };
  const fs::path p = manifest("5");
  const SceneBundle a = CollectBundle(p);
  const std::string hash_a = BundleHash(a);
  const SceneDescription local = LoadScene(p);
  const SceneDescription farm = LoadBundle(dir_, "scene.json");
  ASSERT_EQ(farm.punctual_lights.size(), 1u);
  EXPECT_EQ(farm.punctual_lights[0].intensity, local.punctual_lights[0].intensity);
  EXPECT_EQ(farm.punctual_lights[0].position, local.punctual_lights[0].position);
  manifest("6");
  EXPECT_NE(BundleHash(CollectBundle(p)), hash_a);
}

TEST_F(ManifestLightsTest, ASceneWithoutLightIsAnInputErrorSayingWhy) {
  const std::string obj = DarkObj();
  std::string msg = testing::InputErrorOf([&] { LoadScene(dir_ / obj); });
  EXPECT_EQ(msg.rfind((dir_ / obj).string() + ": ", 0), 0u) << msg;
  EXPECT_THAT(msg, HasSubstr("the scene has no light: no material emits"));
  EXPECT_THAT(msg, HasSubstr("a manifest can add them"));
  EXPECT_THAT(msg, Not(HasSubstr("Ka")));

  const fs::path m = Write("dark.json", R"({"geometry": "dark.obj"})");
  msg = testing::InputErrorOf([&] { LoadScene(m); });
  EXPECT_EQ(msg.rfind(m.string() + ": ", 0), 0u) << msg;
  EXPECT_THAT(msg, HasSubstr("the manifest has no \"lights\""));
  EXPECT_THAT(testing::InputErrorOf([&] { LoadBundle(dir_, "dark.json"); }),
              HasSubstr("the scene has no light"));

  // tinyobjloader's cornell_box.obj: the lamp has Ka 20 20 20 and no Ke.
  Write("ka.mtl", "newmtl light\nKa 20 20 20\nKd 0.5 0.5 0.5\nnewmtl wall\nKa 0 0 0\nKd 0.5 0.5 0.5\n");
  Write("ka.obj", "mtllib ka.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl light\nf 1 2 3\nusemtl wall\nf 1 3 2\n");
  msg = testing::InputErrorOf([&] { LoadScene(dir_ / "ka.obj"); });
  EXPECT_THAT(msg, HasSubstr("material 'light' has Ka but no Ke: Ka is not emission in pf; use Ke"));
  EXPECT_THAT(msg, Not(HasSubstr("'wall'")));

  // A light in the manifest is enough.
  const SceneDescription lit = LoadScene(Write(
      "lit.json", R"({"geometry": "ka.obj", "lights": [{"type": "directional", "direction": [0, 0, -1]}]})"));
  EXPECT_EQ(lit.num_lights, 1u);
}

}  // namespace
}  // namespace pf
