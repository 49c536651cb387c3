// glTF's KHR_materials_transmission transmissionTexture (common/scene/surface_material.h,
// gltf_loader.cpp): the per-texel re-mapping against MetallicRoughnessMaterial of the product by
// hand (the mapping is opaque at transmission 0 and a GGX dielectric above it); the texture's
// codes decoded linearly and its red channel read; the photon walk storing where a texel makes
// the surface opaque; and a plane whose texture has a glass half and an opaque half renders, away
// from the seam, the very pixels of the same plane with two untextured materials.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "common/materials/bsdf.h"
#include "common/scene/metallic_roughness.h"
#include "common/scene/scene_loader.h"
#include "common/scene/surface_material.h"
#include "tests/common/texture_halves_util.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;
using texture_halves::ExpectHalvesMatch;
using texture_halves::ExpectSameMaterial;
using texture_halves::Halves;
using texture_halves::Plane;
using texture_halves::WritePng;

TEST(TransmissionTexture, TexelScalesTransmissionAndDecidesTheLobes) {
  const MetallicRoughness factors{.base_color = Rgb(0.9f, 0.8f, 0.7f),
                                  .metallic = 0.0f,
                                  .roughness = 0.4f,
                                  .transmission = 1.0f,
                                  .ior = 1.4f};
  Material m = MetallicRoughnessMaterial(factors);
  ASSERT_EQ(m.microfacet, Material::Microfacet::kDielectric);
  m.metallic_roughness = factors;
  m.transmission_texture = 0;
  ASSERT_TRUE(IsTextured(m));
  Material out;
  // Red 0: transmission 0, the opaque mapping (ρd = base·0.96, F0 = 0.04, a GGX reflection).
  ApplyTexels(m, MaterialTexels{.transmission = 0.0f}, &out);
  EXPECT_EQ(out.microfacet, Material::Microfacet::kConductor);
  EXPECT_NEAR(out.diffuse_reflectance.r, 0.9f * 0.96f, 1e-6f);
  EXPECT_NEAR(out.specular_reflectance.g, 0.04f, 1e-6f);
  EXPECT_EQ(out.specular_transmittance, Rgb(0.0f));
  EXPECT_EQ(out.microfacet_roughness, 0.4f);
  // Red 0.5: transmission 0.5, the dielectric (the mapping does not scale τs by transmission).
  ApplyTexels(m, MaterialTexels{.transmission = 0.5f}, &out);
  const Material half = MetallicRoughnessMaterial({.base_color = factors.base_color,
                                                   .metallic = 0.0f,
                                                   .roughness = 0.4f,
                                                   .transmission = 0.5f,
                                                   .ior = 1.4f});
  EXPECT_EQ(out.microfacet, half.microfacet);
  EXPECT_EQ(out.specular_transmittance, half.specular_transmittance);
  EXPECT_EQ(out.diffuse_reflectance, Rgb(0.0f));
  EXPECT_EQ(out.ior, 1.4f);
  // White texels: the untextured material bit for bit.
  ApplyTexels(m, MaterialTexels{}, &out);
  ExpectSameMaterial(out, m);
  EXPECT_EQ(out.ior, m.ior);
}

// The photon walk stores on a surface only where it has a diffuse lobe, decided per material: a
// transmissive material that a texel can make opaque must store.
TEST(TransmissionTexture, AGlassThatATexelCanMakeOpaqueStoresPhotons) {
  // The material mapped from `p`, keeping `p`, with the given textures.
  const auto mapped = [](const MetallicRoughness& p, int32_t transmission_texture, int32_t mr_texture) {
    Material m = MetallicRoughnessMaterial(p);
    m.metallic_roughness = p;
    m.transmission_texture = transmission_texture;
    m.metallic_roughness_texture = mr_texture;
    return m;
  };
  const auto stores = [](const Material& m) { return WalkRoulette::Of(m, BsdfLobes::Of(m)).has_diffuse; };
  const MetallicRoughness glass{.base_color = Rgb(0.8f), .metallic = 0.0f, .transmission = 1.0f};
  EXPECT_FALSE(stores(mapped(glass, -1, -1))) << "untextured glass stores nothing";
  EXPECT_TRUE(stores(mapped(glass, 0, -1)));
  // metallicFactor 1: only a metallic-roughness texture (its blue) can lower it.
  MetallicRoughness metal_glass = glass;
  metal_glass.metallic = 1.0f;
  EXPECT_TRUE(stores(mapped(metal_glass, 0, 1)));
  EXPECT_FALSE(stores(mapped(metal_glass, 0, -1))) << "a metal has no diffuse lobe at any texel";
  // A black base colour has no diffuse lobe at any texel.
  MetallicRoughness black = glass;
  black.base_color = Rgb(0.0f);
  EXPECT_FALSE(stores(mapped(black, 0, -1)));
}

// A sun from over the camera's shoulder and a blue sky: the glass half shows the sky through it,
// the opaque half the sun's and the sky's diffuse light. Nothing but the sky lies behind the
// plane: no path comes back to it, where the texture's bilinear seam (glass up to x = 1/8 m)
// would meet scene B's sharp one (x = 0).
constexpr const char* kCamera =
    R"("lights": [{"type": "directional", "direction": [-0.3, -0.2, -1], "intensity": 3}],
    "environment": {"color": [0.2, 0.3, 0.6]},
    "cameras": [{"name": "front", "eye": [0, 0, 2.4142], "look_at": [0, 0, 0], "up": [0, 1, 0],
                 "fov": 45, "resolution": [32, 32]}])";

// Scene A: one material, transmissionFactor 1, its transmission texture (8 x 8, clamped, linear)
// red 255 on the left half, 0 on the right: rough glass and an opaque dielectric. Scene B: the same
// triangles, the left with transmission 1, the right with 0, untextured.
void WriteScenes(const test_util::TempDir& dir) {
  WritePng(dir.path() / "t.png", 8, 8, Halves({255, 9, 9}, {0, 9, 9}));
  const std::string material =
      R"("pbrMetallicRoughness":{"baseColorFactor":[0.9,0.6,0.3,1],"metallicFactor":0,
                                                          "roughnessFactor":0.3})";
  const auto transmission = [](const std::string& factor, const std::string& texture) {
    return R"(,"extensions":{"KHR_materials_transmission":{"transmissionFactor":)" + factor + texture + "}}";
  };
  const gltf_test::GltfBuilder a = Plane(), b = Plane();
  const std::string a_json =
      R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"extensionsUsed":["KHR_materials_transmission"],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2},"indices":5,"material":0}]}],
      "samplers":[{"wrapS":33071,"wrapT":33071}],"textures":[{"source":0,"sampler":0}],"images":[{"uri":"t.png"}],
      "materials":[{"name":"textured",)" +
      material + transmission("1", R"(,"transmissionTexture":{"index":0})") + "}]";
  const std::string b_json =
      R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],"extensionsUsed":["KHR_materials_transmission"],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},"indices":3,"material":0},
                               {"attributes":{"POSITION":0,"NORMAL":1},"indices":4,"material":1}]}],
      "materials":[{"name":"glass",)" +
      material + transmission("1", "") + R"(},{"name":"opaque",)" + material + "}]";
  dir.Write("a.gltf", a.Json(a_json));
  dir.Write("b.gltf", b.Json(b_json));
  dir.Write("a.json", std::string(R"({"version": 1, "geometry": "a.gltf", )") + kCamera + "}");
  dir.Write("b.json", std::string(R"({"version": 1, "geometry": "b.gltf", )") + kCamera + "}");
}

TEST(TransmissionTexture, LoaderDecodesTheTextureLinearlyAndStopsWarning) {
  test_util::TempDir dir("pf_transmission_texture_test");
  WriteScenes(dir);
  const SceneDescription s = LoadScene(dir.path() / "a.json");
  ASSERT_EQ(s.textures.size(), 1u);
  ASSERT_EQ(s.materials[0].transmission_texture, 0);
  // Code 9 in G: 9/255 linearly (the sRGB curve would give 0.0027); red 255 on the left.
  EXPECT_FLOAT_EQ(s.textures[0].Lookup({0.1f, 0.5f}).g, 9.0f / 255.0f);
  EXPECT_FLOAT_EQ(s.textures[0].Lookup({0.1f, 0.5f}).r, 1.0f);
  EXPECT_FLOAT_EQ(s.textures[0].Lookup({0.9f, 0.5f}).r, 0.0f);
  EXPECT_THAT(::testing::PrintToString(s.warnings), Not(HasSubstr("transmissionTexture")));
}

// A manifest override of roughness or ior holds at textured hits too: the texture re-maps the
// glTF parameters, which take the override.
TEST(TransmissionTexture, ManifestOverridesHoldAtTexturedHits) {
  test_util::TempDir dir("pf_transmission_texture_test");
  WriteScenes(dir);
  dir.Write("o.json", std::string(R"({"version": 1, "geometry": "a.gltf",
      "materials": {"textured": {"roughness": 0.05, "ior": 1.2}}, )") +
                          kCamera + "}");
  const SceneDescription s = LoadScene(dir.path() / "o.json");
  const Material& m = s.materials[0];
  ASSERT_EQ(m.transmission_texture, 0);
  Material glass, opaque;
  ApplyTexels(m, MaterialTexels{.transmission = 1.0f}, &glass);
  ApplyTexels(m, MaterialTexels{.transmission = 0.0f}, &opaque);
  EXPECT_EQ(glass.microfacet, Material::Microfacet::kDielectric);
  EXPECT_EQ(glass.microfacet_roughness, 0.05f);
  EXPECT_EQ(glass.ior, 1.2f);
  EXPECT_EQ(opaque.microfacet_roughness, 0.05f);
}

TEST(TransmissionTexture, ATextureOnAFactorOfZeroIsAWarningNotADecode) {
  test_util::TempDir dir("pf_transmission_texture_test");
  WriteScenes(dir);
  std::string gltf = test_util::ReadFileBytes(dir.path() / "a.gltf");
  const std::string factor = R"("transmissionFactor":1)";
  gltf.replace(gltf.find(factor), factor.size(), R"("transmissionFactor":0)");
  dir.Write("a.gltf", gltf);
  const SceneDescription s = LoadScene(dir.path() / "a.json");
  EXPECT_TRUE(s.textures.empty());
  EXPECT_EQ(s.materials[0].transmission_texture, -1);
  EXPECT_THAT(
      ::testing::PrintToString(s.warnings),
      HasSubstr("materials[0].extensions.KHR_materials_transmission.transmissionTexture: not applied: "
                "transmissionFactor is 0"));
}

TEST(TransmissionTexture, HalvesRenderAsTheirUntexturedMaterialsPathTracer) {
  test_util::TempDir dir("pf_transmission_texture_test");
  WriteScenes(dir);
  ExpectHalvesMatch(dir.path() / "a.json", dir.path() / "b.json", "path");
}

TEST(TransmissionTexture, HalvesRenderAsTheirUntexturedMaterialsPhotonMap) {
  test_util::TempDir dir("pf_transmission_texture_test");
  WriteScenes(dir);
  ExpectHalvesMatch(dir.path() / "a.json", dir.path() / "b.json", "photonmap");
}

}  // namespace
}  // namespace pf
