// SceneBudget::max_texels (common/scene/scene_budget.h): the pixels of all the images one load
// decodes — glTF textures, OBJ maps, the environment — are charged to one allowance, from each
// image's header, and the image that would cross it is refused naming its element and the budget.
// Small budgets here; the default's size is in docs/security.md.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <functional>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/image/image_file.h"
#include "common/scene/environment.h"
#include "common/scene/gltf_loader.h"
#include "common/scene/obj_loader.h"
#include "common/scene/scene_budget.h"
#include "common/scene/scene_bundle.h"
#include "tests/common/gltf_test_util.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using gltf_test::GltfBuilder;
using ::testing::HasSubstr;

// A grey 8-bit RGB PNG of `w` x `h`.
void WritePng(const std::filesystem::path& path, int w, int h) {
  const std::vector<unsigned char> rgb(size_t(w) * size_t(h) * 3, 128);
  ASSERT_NE(stbi_write_png(path.string().c_str(), w, h, 3, rgb.data(), w * 3), 0);
}

// A one-triangle glTF whose material uses a.png (8 x 8) as its base colour and b.png (8 x 4) as
// its metallic-roughness texture, and a lamp.
std::filesystem::path WriteGltf(const test_util::TempDir& dir) {
  WritePng(dir.path() / "a.png", 8, 8);
  WritePng(dir.path() / "b.png", 8, 4);
  GltfBuilder b;
  b.AddVec3({0, 0, 0, 1, 0, 0, 0, 1, 0});
  b.AddVec2({0, 0, 1, 0, 0, 1});
  b.AddIndices16({0, 1, 2});
  const std::string rest = R"("scenes":[{"nodes":[0,1]}],"nodes":[{"mesh":0},
      {"translation":[0,0,2],"extensions":{"KHR_lights_punctual":{"light":0}}}],
      "extensionsUsed":["KHR_lights_punctual"],
      "extensions":{"KHR_lights_punctual":{"lights":[{"type":"point","intensity":10}]}},
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":1},"indices":2,"material":0}]}],
      "textures":[{"source":0},{"source":1}],"images":[{"uri":"a.png"},{"uri":"b.png"}],
      "materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0},
                                            "metallicRoughnessTexture":{"index":1}}}])";
  return dir.Write("s.gltf", b.Json(rest));
}

std::string LimitErrorOf(const std::function<void()>& load) {
  try {
    load();
  } catch (const LimitError& e) {
    return e.what();
  }
  ADD_FAILURE() << "loaded within the budget";
  return "";
}

TEST(TexelBudget, AGltfsImagesTogetherAreRefusedPastTheBudget) {
  test_util::TempDir dir("pf_texel_budget");
  const std::filesystem::path gltf = WriteGltf(dir);
  // 64 + 32 pixels: 96 fit, 95 do not, and the image named is the one that crossed.
  EXPECT_EQ(LoadGltf(gltf, dir.path(), SceneBudget{.max_texels = 96}).textures.size(), 2u);
  const std::string error = LimitErrorOf([&] { LoadGltf(gltf, dir.path(), SceneBudget{.max_texels = 95}); });
  EXPECT_THAT(error,
              HasSubstr("s.gltf: materials[0].pbrMetallicRoughness.metallicRoughnessTexture: textures[1]: "
                        "images[1] 'b.png': image of 8x4 pixels would bring the scene's images to 96 "
                        "pixels, more than the budget of 95 (SceneBudget::max_texels"));
  // An allowance shared with the load's other images: what the glTF took, the environment cannot.
  PixelAllowance shared(100);
  LoadGltf(gltf, dir.path(), {}, &shared);
  EXPECT_EQ(shared.used(), 96u);
  WritePng(dir.path() / "sky.png", 3, 2);
  Environment sky;
  sky.file = "sky.png";
  EXPECT_THAT(LimitErrorOf([&] {
                LoadEnvironmentImage(dir.path() / "s.json", dir.path(), dir.path(), &sky, &shared);
              }),
              HasSubstr("sky.png: image of 3x2 pixels would bring the scene's images to 102"));
}

TEST(TexelBudget, AnObjsMapsTogetherAreRefusedPastTheBudget) {
  test_util::TempDir dir("pf_texel_budget");
  WritePng(dir.path() / "a.png", 8, 8);
  WritePng(dir.path() / "b.png", 8, 4);
  dir.Write("s.mtl",
            "newmtl a\nKd 1 1 1\nmap_Kd a.png\nnewmtl b\nKd 1 1 1\nmap_Kd b.png\nnewmtl lamp\nKe 1 1 1\n");
  const std::filesystem::path obj =
      dir.Write("s.obj",
                "mtllib s.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                "usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 3/3 2/2\nusemtl lamp\nf 1 2 3\n");
  EXPECT_EQ(LoadObj(obj, dir.path(), SceneBudget{.max_texels = 96}).textures.size(), 2u);
  EXPECT_THAT(LimitErrorOf([&] { LoadObj(obj, dir.path(), SceneBudget{.max_texels = 95}); }),
              HasSubstr("material 'b': map_Kd 'b.png': image of 8x4 pixels would bring"));
}

// The default budget, as every load has it (pf render, the coordinator's upload, a worker's
// bundle): a PNG header claiming 16384² pixels (no pixel data behind it) after a 1 x 1 texture is
// refused from its header, as a LimitError through LoadBundle too (RESOURCE_EXHAUSTED on the farm).
TEST(TexelBudget, TheDefaultBudgetRefusesFromTheHeaderThroughABundle) {
  test_util::TempDir dir("pf_texel_budget");
  const std::filesystem::path gltf = WriteGltf(dir);
  WritePng(dir.path() / "a.png", 1, 1);
  std::string png("\x89PNG\r\n\x1a\n", 8);
  png += std::string("\0\0\0\x0d", 4) + "IHDR" + std::string("\0\0\x40\0\0\0\x40\0\x08\x02\0\0\0", 13);
  png += std::string(4, '\0');
  dir.Write("b.png", png);
  EXPECT_THAT(
      LimitErrorOf([&] { LoadBundle(dir.path(), "s.gltf"); }),
      HasSubstr("s.gltf: materials[0].pbrMetallicRoughness.metallicRoughnessTexture: textures[1]: "
                "images[1] 'b.png': image of 16384x16384 pixels would bring the scene's images to 268435457 "
                "pixels, more than the budget of 268435456"));
}

}  // namespace
}  // namespace pf
