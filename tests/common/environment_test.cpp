// The environment as a scene declares it (common/scene/environment.h): the manifest's
// "environment" key, the image LoadScene reads for it, the errors of bad input (naming the file
// and the key), a scene lit by it alone, and its image travelling in the scene's bundle.
#include "common/scene/environment.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/image/exr_io.h"
#include "common/scene/manifest.h"
#include "common/scene/scene_bundle.h"
#include "common/scene/scene_loader.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using std::filesystem::path;
using ::testing::HasSubstr;

// A one-triangle OBJ without any emitter, and a manifest over it with `environment` (JSON).
class EnvironmentTest : public test_util::TempDirTest {
 protected:
  path Manifest(const std::string& environment) const {
    tmp_.Write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    return tmp_.Write("scene.json",
                      "{\"geometry\": \"tri.obj\"" +
                          (environment.empty() ? std::string() : ", \"environment\": " + environment) + "}");
  }
  void WriteHdr(const std::string& name, int w, int h, float value) const {
    const std::vector<float> rgb(size_t(w * h * 3), value);
    ASSERT_TRUE(stbi_write_hdr((dir_ / name).c_str(), w, h, 3, rgb.data()));
  }
  static std::string ErrorOf(const path& manifest) {
    try {
      LoadScene(manifest);
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "loaded";
    return "";
  }
};

TEST_F(EnvironmentTest, ConstantColourAloneLightsTheScene) {
  const SceneDescription s = LoadScene(Manifest(R"({"color": [0.5, 1, 2], "strength": 2, "rotation": 30})"));
  ASSERT_TRUE(s.environment.has_value());
  EXPECT_EQ(s.num_lights, 1u);
  EXPECT_EQ(s.environment->light, 0u);
  EXPECT_EQ(s.environment->rotation_deg, 30.0f);
  EXPECT_EQ(s.environment->Radiance(Vec3(0, 1, 0)).b, 4.0f);
  EXPECT_EQ(s.environment->image, nullptr);
}

TEST_F(EnvironmentTest, ImageFileIsRead) {
  WriteHdr("sky.hdr", 8, 4, 0.75f);
  const SceneDescription s = LoadScene(Manifest(R"({"file": "sky.hdr"})"));
  ASSERT_TRUE(s.environment && s.environment->image);
  EXPECT_EQ(s.environment->width(), 8);
  EXPECT_EQ(s.environment->height(), 4);
  EXPECT_EQ(s.environment->Radiance(Vec3(0, -1, 0)).g, 0.75f);
}

TEST_F(EnvironmentTest, WithoutItASceneWithoutLightIsStillRefused) {
  EXPECT_THAT(ErrorOf(Manifest("")), HasSubstr("the manifest has no \"lights\" and no \"environment\""));
}

TEST_F(EnvironmentTest, BadInputNamesTheFileAndTheKey) {
  EXPECT_THAT(ErrorOf(Manifest(R"({"file": "nope.hdr"})")), HasSubstr("nope.hdr: image file not found"));
  tmp_.Write("bad.hdr", "#?RADIANCE\ngarbage");
  EXPECT_THAT(ErrorOf(Manifest(R"({"file": "bad.hdr"})")), HasSubstr("bad.hdr: cannot decode the image"));
  Image nan(2, 1);
  nan.at(1, 0).g = std::numeric_limits<float>::quiet_NaN();
  WriteExr(dir_ / "nan.exr", nan);
  EXPECT_THAT(ErrorOf(Manifest(R"({"file": "nan.exr"})")),
              HasSubstr("nan.exr: pixel (1, 0) is not a finite"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"file": "../outside.hdr"})")),
              HasSubstr("key 'environment.file': '../outside.hdr' resolves outside"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"color": [1, -1, 0]})")),
              HasSubstr("key 'environment.color': expected 3 finite non-negative numbers"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"color": [1, "nan", 0]})")), HasSubstr("key 'environment.color'"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"color": 0})")),
              HasSubstr("key 'environment.color': expected a colour that is not black"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"color": 1, "file": "sky.hdr"})")),
              HasSubstr("key 'environment': expected exactly one of"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"strength": 2})")),
              HasSubstr("key 'environment': expected exactly one of"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"color": 1, "strength": -1})")), HasSubstr("key 'environment.strength'"));
  EXPECT_THAT(ErrorOf(Manifest(R"({"color": 1, "rotation": "left"})")),
              HasSubstr("key 'environment.rotation'"));
  EXPECT_THAT(ErrorOf(Manifest(R"([1, 2])")), HasSubstr("key 'environment': expected an object"));
  WriteHdr("black.hdr", 4, 2, 0.0f);
  EXPECT_THAT(ErrorOf(Manifest(R"({"file": "black.hdr"})")),
              HasSubstr("key 'environment.file': 'black.hdr' is black"));
}

// The environment's image is an input: shipped in the bundle even as an .exr (renders kept next to
// a scene are not), so its content is part of the bundle's hash.
TEST_F(EnvironmentTest, ItsImageTravelsInTheBundle) {
  Image sky(4, 2);
  sky.at(0, 0) = Rgb(1.0f);
  WriteExr(dir_ / "sky.exr", sky);
  WriteExr(dir_ / "render.exr", sky);
  const path manifest = Manifest(R"({"file": "sky.exr"})");
  const SceneBundle bundle = CollectBundle(manifest);
  std::vector<std::string> names;
  for (const auto& [path, content] : bundle.files) names.push_back(path);
  EXPECT_THAT(names, ::testing::ElementsAre("scene.json", "sky.exr", "tri.obj"));
  const std::string hash = BundleHash(bundle);
  sky.at(0, 0) = Rgb(2.0f);
  WriteExr(dir_ / "sky.exr", sky);
  EXPECT_NE(BundleHash(CollectBundle(manifest)), hash) << "another sky is another scene";
  // And the bundle loads where it is written.
  test_util::TempDir other("pf_env_bundle");
  WriteBundle(bundle, other.path());
  const SceneDescription s = LoadBundle(other.path(), bundle.entry);
  ASSERT_TRUE(s.environment && s.environment->image);
  EXPECT_EQ(s.environment->image->at(0, 0).r, 1.0f);
}

}  // namespace
}  // namespace pf
