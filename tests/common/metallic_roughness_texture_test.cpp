// glTF's metallicRoughnessTexture (common/scene/surface_material.h, gltf_loader.cpp,
// gltf_textures.h): the per-texel re-mapping against MetallicRoughnessMaterial of the products
// by hand; the texture's codes decoded linearly (not by the sRGB curve a base colour takes); and a
// plane whose texture has a metal half and a dielectric half renders, away from the seam, the
// very pixels of the same plane with two untextured materials of those factors.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "common/image/image_file.h"
#include "common/scene/metallic_roughness.h"
#include "common/scene/scene_loader.h"
#include "common/scene/surface_material.h"
#include "tests/common/gltf_test_util.h"
#include "tests/common/scene_render_util.h"
#include "tests/common/texture_halves_util.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using gltf_test::GltfBuilder;
using ::testing::HasSubstr;
using ::testing::Not;
using texture_halves::ExpectHalvesMatch;
using texture_halves::ExpectSameMaterial;
using texture_halves::Halves;
using texture_halves::Plane;
using texture_halves::WritePng;

TEST(MetallicRoughnessTexture, TexelScalesMetallicByBlueAndRoughnessByGreen) {
  const MetallicRoughness factors{.base_color = Rgb(0.5f, 0.25f, 1.0f), .metallic = 0.8f, .roughness = 0.6f};
  Material m = MetallicRoughnessMaterial(factors);
  m.metallic_roughness = factors;
  m.metallic_roughness_texture = 0;
  Material out;
  // R is unused (glTF puts occlusion there); G = 0.5, B = 0.25: metallic 0.2, roughness 0.3.
  ApplyTexels(m, MaterialTexels{.metallic_roughness = Rgb(0.9f, 0.5f, 0.25f)}, &out);
  const Material want = MetallicRoughnessMaterial(
      {.base_color = factors.base_color, .metallic = 0.8f * 0.25f, .roughness = 0.6f * 0.5f});
  ExpectSameMaterial(out, want);
  // By hand: ρd = base·(1 − 0.2)·0.96, F0 = 0.04·0.8 + base·0.2.
  EXPECT_NEAR(out.diffuse_reflectance.r, 0.5f * 0.8f * 0.96f, 1e-6f);
  EXPECT_NEAR(out.specular_reflectance.g, 0.04f * 0.8f + 0.25f * 0.2f, 1e-6f);
  EXPECT_NEAR(out.microfacet_roughness, 0.3f, 1e-6f);
  // White texels: the untextured material bit for bit.
  ApplyTexels(m, MaterialTexels{}, &out);
  ExpectSameMaterial(out, MetallicRoughnessMaterial(factors));
  // With the base colour texture too: both apply.
  m.base_color_texture = 1;
  ApplyTexels(m, MaterialTexels{.base_color = Rgb(0.5f), .metallic_roughness = Rgb(1.0f, 1.0f, 0.0f)}, &out);
  ExpectSameMaterial(
      out, MetallicRoughnessMaterial(
               {.base_color = factors.base_color * Rgb(0.5f), .metallic = 0.0f, .roughness = 0.6f}));
}

TEST(MetallicRoughnessTexture, BlueBelowOneMakesATransmissiveMaterialADielectric) {
  const MetallicRoughness factors{.metallic = 1.0f, .roughness = 0.5f, .transmission = 1.0f, .ior = 1.4f};
  Material m = MetallicRoughnessMaterial(factors);  // a metal: transmission needs metallic < 1
  ASSERT_EQ(m.microfacet, Material::Microfacet::kConductor);
  m.metallic_roughness = factors;
  m.metallic_roughness_texture = 0;
  Material out;
  ApplyTexels(m, MaterialTexels{.metallic_roughness = Rgb(1.0f, 1.0f, 0.0f)}, &out);
  EXPECT_EQ(out.microfacet, Material::Microfacet::kDielectric);
  EXPECT_EQ(out.ior, 1.4f);
  EXPECT_EQ(out.specular_transmittance, Rgb(1.0f));
  EXPECT_EQ(out.diffuse_reflectance, Rgb(0.0f));
}

// A sun from over the camera's shoulder: the rough metal's highlight and the dielectric's diffuse
// light differ (under a uniform sky both would show about their albedo).
constexpr const char* kCamera =
    R"("lights": [{"type": "directional", "direction": [-0.3, -0.2, -1], "intensity": 3}],
    "cameras": [{"name": "front", "eye": [0, 0, 2.4142], "look_at": [0, 0, 0], "up": [0, 1, 0],
                 "fov": 45, "resolution": [32, 32]}])";

// Scene A: one material, metallicFactor 1, roughnessFactor 0.5, its metallic-roughness texture
// (8 x 8, clamped) (G, B) = (255, 255) on the left half, (0, 0) on the right: a rough metal and
// a smooth dielectric. Scene B: the same triangles, the left with factors (1, 0.5), the right
// with (0, 0), untextured.
std::filesystem::path WriteScenes(const test_util::TempDir& dir) {
  WritePng(dir.path() / "mr.png", 8, 8, Halves({77, 255, 255}, {77, 0, 0}));
  const std::string base = R"("baseColorFactor":[0.9,0.6,0.3,1])";
  const std::string a =
      R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2},"indices":5,"material":0}]}],
      "samplers":[{"wrapS":33071,"wrapT":33071}],"textures":[{"source":0,"sampler":0}],"images":[{"uri":"mr.png"}],
      "materials":[{"name":"textured","pbrMetallicRoughness":{)" +
      base + R"(,"metallicFactor":1,"roughnessFactor":0.5,"metallicRoughnessTexture":{"index":0}}}])";
  const std::string b = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},"indices":3,"material":0},
                               {"attributes":{"POSITION":0,"NORMAL":1},"indices":4,"material":1}]}],
      "materials":[{"name":"metal","pbrMetallicRoughness":{)" +
                        base + R"(,"metallicFactor":1,"roughnessFactor":0.5}},
                   {"name":"dielectric","pbrMetallicRoughness":{)" +
                        base + R"(,"metallicFactor":0,"roughnessFactor":0}}])";
  dir.Write("a.gltf", Plane().Json(a));
  dir.Write("b.gltf", Plane().Json(b));
  dir.Write("a.json", std::string(R"({"version": 1, "geometry": "a.gltf", )") + kCamera + "}");
  dir.Write("b.json", std::string(R"({"version": 1, "geometry": "b.gltf", )") + kCamera + "}");
  return dir.path();
}

TEST(MetallicRoughnessTexture, LoaderDecodesTheTextureLinearlyAndStopsWarning) {
  test_util::TempDir dir("pf_mr_texture_test");
  WriteScenes(dir);
  const SceneDescription s = LoadScene(dir.path() / "a.json");
  ASSERT_EQ(s.textures.size(), 1u);
  ASSERT_EQ(s.materials[0].metallic_roughness_texture, 0);
  EXPECT_EQ(s.materials[0].base_color_texture, -1);
  ASSERT_EQ(s.uvs.size(), s.positions.size());
  // Code 77 in R: 77/255 linearly (the sRGB curve would give 0.0742).
  EXPECT_FLOAT_EQ(s.textures[0].Lookup({0.1f, 0.5f}).r, 77.0f / 255.0f);
  EXPECT_THAT(::testing::PrintToString(s.warnings), Not(HasSubstr("metallicRoughnessTexture")));
}

TEST(MetallicRoughnessTexture, ImageSharedByBaseColourAndMetallicRoughnessIsDecodedBothWays) {
  test_util::TempDir dir("pf_mr_texture_test");
  WritePng(dir.path() / "t.png", 1, 1, {128, 128, 128});
  const std::string rest = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2},"indices":5,"material":0}]}],
      "textures":[{"source":0}],"images":[{"uri":"t.png"}],
      "materials":[{"pbrMetallicRoughness":{"baseColorTexture":{"index":0},"metallicRoughnessTexture":{"index":0}},
                    "occlusionTexture":{"index":0}}])";
  dir.Write("s.gltf", Plane().Json(rest));
  const SceneDescription s =
      LoadScene(dir.Write("s.json", std::string(R"({"version": 1, "geometry": "s.gltf", )") + kCamera + "}"));
  ASSERT_EQ(s.textures.size(), 2u);
  const Material& m = s.materials[0];
  EXPECT_NEAR(s.textures[size_t(m.base_color_texture)].Lookup({0.5f, 0.5f}).g, SrgbToLinear8(128), 1e-7f);
  EXPECT_NEAR(s.textures[size_t(m.metallic_roughness_texture)].Lookup({0.5f, 0.5f}).g, 128.0f / 255.0f,
              1e-7f);
  // The warning names the slots still unapplied, not this one.
  EXPECT_THAT(::testing::PrintToString(s.warnings), HasSubstr("textures not applied: occlusionTexture ("));
}

// A rough metal half and a smooth dielectric half, each the very pixels of its untextured material.
void ExpectHalvesMatchUntexturedMaterials(const char* integrator) {
  test_util::TempDir dir("pf_mr_texture_test");
  WriteScenes(dir);
  ExpectHalvesMatch(dir.path() / "a.json", dir.path() / "b.json", integrator);
}

TEST(MetallicRoughnessTexture, HalvesRenderAsTheirUntexturedMaterialsPathTracer) {
  ExpectHalvesMatchUntexturedMaterials("path");
}

TEST(MetallicRoughnessTexture, HalvesRenderAsTheirUntexturedMaterialsPhotonMap) {
  ExpectHalvesMatchUntexturedMaterials("photonmap");
}

}  // namespace
}  // namespace pf
