// Textured emission (glTF emissiveTexture, OBJ map_Ke; scene.h Material::emission_texture,
// lights/light_sampler.h, photon_tracer.cpp): Le = emission × texel at every point. An emitter
// whose texture is white on one half and black on the other, 1 m above a large floor:
// - the photons landing on the floor straight from it carry its analytic power π·Le·A/2;
// - the light sampler's power (from the texture's mean over each triangle) is that power;
// - the camera sees Le through the white half and nothing through the black one, both integrators;
// - the floor, lit by next-event estimation and photons, matches the same floor under an
//   untextured emitter covering the white half only (up to the filter's blur of the seam).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <cmath>
#include <iostream>
#include <numbers>
#include <string>
#include <vector>

#include "common/photon/photon_maps.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"
#include "tests/common/gltf_test_util.h"
#include "tests/common/scene_render_util.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

constexpr float kLe = 2.0f;

// 8 x 8 grey PNG: white (255) where x < 4, black elsewhere.
void WriteHalfWhite(const std::filesystem::path& path) {
  std::vector<unsigned char> codes;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) codes.push_back(x < 4 ? 255 : 0);
  ASSERT_NE(stbi_write_png(path.string().c_str(), 8, 8, 1, codes.data(), 8), 0);
}

// The emitter: 2 x 2 m at z = 1 facing down (−z), Ke 2, map_Ke white on x < 0 (vt u = (x + 1)/2),
// or (`split`) the same square as two quads, the x < 0 one emitting Ke 2 untextured and the other
// black. A 200 x 200 m floor (Kd 0.5) at z = 0. `camera`: the manifest's cameras.
std::filesystem::path WriteScene(const test_util::TempDir& dir, bool split, const std::string& camera) {
  WriteHalfWhite(dir.path() / "half.png");
  dir.Write("scene.mtl",
            "newmtl floor\nKd 0.5 0.5 0.5\n"
            "newmtl lamp\nKd 0 0 0\nKe 2 2 2\nmap_Ke -clamp on half.png\n"
            "newmtl plain_lamp\nKd 0 0 0\nKe 2 2 2\n"
            "newmtl dark\nKd 0 0 0\n");
  const std::string floor =
      "v -100 -100 0\nv 100 -100 0\nv 100 100 0\nv -100 100 0\nusemtl floor\nf 1 2 3\nf 1 3 4\n";
  const std::string lamp = split ? "v -1 -1 1\nv 0 -1 1\nv 0 1 1\nv -1 1 1\nv 1 -1 1\nv 1 1 1\n"
                                   "usemtl plain_lamp\nf 5 7 6\nf 5 8 7\nusemtl dark\nf 6 10 9\nf 6 7 10\n"
                                 : "v -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
                                   "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                   "usemtl lamp\nf 5/1 7/3 6/2\nf 5/1 8/4 7/3\n";
  dir.Write("scene.obj", "mtllib scene.mtl\n" + floor + lamp);
  return dir.Write("scene.json", R"({"version": 1, "geometry": "scene.obj", "cameras": [)" + camera + "]}");
}

constexpr const char* kUp = R"({"name": "up", "eye": [0, 0, 0.01], "look_at": [0, 0, 1], "up": [0, 1, 0],
    "fov": 90, "resolution": [32, 32]})";
constexpr const char* kDown = R"({"name": "down", "eye": [0, 0, 0.5], "look_at": [0, 0, 0], "up": [0, 1, 0],
    "fov": 90, "resolution": [32, 32]})";

TEST(EmissionTexture, ObjMapKeIsLoadedAsAnSrgbEmissionTexture) {
  test_util::TempDir dir("pf_emission_texture_test");
  const SceneDescription s = LoadScene(WriteScene(dir, false, kUp));
  const Material& lamp = s.materials[1];
  ASSERT_GE(lamp.emission_texture, 0);
  EXPECT_EQ(lamp.emission, Rgb(kLe));
  EXPECT_FLOAT_EQ(s.textures[size_t(lamp.emission_texture)].Lookup({0.1f, 0.5f}).r, 1.0f);
  EXPECT_FLOAT_EQ(s.textures[size_t(lamp.emission_texture)].Lookup({0.9f, 0.5f}).r, 0.0f);
  EXPECT_THAT(::testing::PrintToString(s.warnings), Not(HasSubstr("map_Ke")));
}

TEST(EmissionTexture, GltfEmissiveTextureIsLoaded) {
  test_util::TempDir dir("pf_emission_texture_test");
  WriteHalfWhite(dir.path() / "half.png");
  gltf_test::GltfBuilder b;
  b.AddVec3({-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0});
  b.AddVec2({0, 1, 1, 1, 1, 0, 0, 0});
  b.AddIndices16({0, 1, 2, 0, 2, 3});
  const SceneDescription s =
      LoadScene(dir.Write("lamp.gltf", b.Json(R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":1},"indices":2,"material":0}]}],
      "textures":[{"source":0}],"images":[{"uri":"half.png"}],
      "materials":[{"emissiveFactor":[1,0.5,1],"emissiveTexture":{"index":0},
                    "extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":4}}}])")));
  const Material& m = s.materials[0];
  ASSERT_GE(m.emission_texture, 0);
  EXPECT_EQ(m.emission, Rgb(4.0f, 2.0f, 4.0f));
  ASSERT_EQ(s.uvs.size(), s.positions.size());
  EXPECT_THAT(::testing::PrintToString(s.warnings), Not(HasSubstr("emissiveTexture")));
}

// Φ = π·Le·A·(mean texel) = π·2·4·½ = 4π W per channel: the light sampler's estimate (within
// 0.5 %), and the power of the photons landing straight on the floor (all but ~1e-4 of them:
// the floor is 100 m wide at 1 m below the lamp), centred under the white half.
TEST(EmissionTexture, PhotonsCarryTheAnalyticPower) {
  test_util::TempDir dir("pf_emission_texture_test");
  const SceneRuntime scene(LoadScene(WriteScene(dir, false, kDown)));
  const float analytic = std::numbers::pi_v<float> * kLe * 4.0f * 0.5f;
  EXPECT_NEAR(scene.lights.total_power().g, analytic, 0.005f * analytic);
  PhotonMapsOptions options;
  options.tracing.photons = 100000;
  options.separate_direct = true;
  const PhotonMaps maps = PhotonMaps::Build(scene.accel, scene.lights, options);
  ASSERT_TRUE(maps.direct);
  Rgb direct(0.0f);
  double moment_x = 0;  // Σ Φ·x over the photons
  for (const Photon& p : maps.direct->photons()) {
    direct += p.Power();
    moment_x += double(p.Power().g) * (double(p.Position().x) + scene.description.origin.x);
  }
  // Where the power lands: the emitted power's mean x, shifted by the cosine lobe's spread
  // (symmetric): over the texture, ∫x·f / ∫f = −0.5 + 2∫₀^⅛ x(½ − 4x) dx = −0.4974 (f the
  // bilinear texel across the lamp, its seam blurred over ±⅛ m). Uniform emission would give 0.
  const double mean_x = moment_x / double(direct.g);
  std::cout << "direct photons " << maps.direct->size() << " carry " << direct.g << " W (analytic "
            << analytic << "); light sampler " << scene.lights.total_power().g << " W; power-weighted mean x "
            << mean_x << " (analytic -0.4974)\n";
  EXPECT_NEAR(direct.g, analytic, 0.01f * analytic);
  EXPECT_NEAR(mean_x, -0.4974, 0.03);
}

// The camera just above the floor looks up at the lamp (image right = world −x): Le through the
// white half, 0 through the black one; the seam's 1/8 m blur is left out.
void ExpectTexelRadianceSeenDirectly(const char* integrator) {
  test_util::TempDir dir("pf_emission_texture_test");
  const Image image = render_test::RenderScene(WriteScene(dir, false, kUp), integrator, 4, 20000);
  for (int y = 2; y < 30; ++y)
    for (int x = 2; x < 30; ++x) {
      if (x > 12 && x < 19) continue;
      // x ≥ 19: world x < −0.2, the white half (its bilinear texel is 1 to a float rounding).
      const float want = x >= 19 ? kLe : 0.0f;
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(image.at(x, y)[c], want, 1e-5f) << integrator << " pixel " << x << ", " << y;
    }
}

TEST(EmissionTexture, TexelRadianceSeenDirectlyPathTracer) {
  ExpectTexelRadianceSeenDirectly("path");
}

TEST(EmissionTexture, TexelRadianceSeenDirectlyPhotonMap) {
  ExpectTexelRadianceSeenDirectly("photonmap");
}

// The floor seen from 0.5 m above: its mean radiance under the textured lamp against the split
// lamp's (the same light but for the seam's blur, which moves light by at most 1/8 m).
void ExpectFloorLitLikeTheSplitLamp(const char* integrator) {
  test_util::TempDir textured_dir("pf_emission_texture_test");
  test_util::TempDir split_dir("pf_emission_texture_test");
  const Image textured =
      render_test::RenderScene(WriteScene(textured_dir, false, kDown), integrator, 16, 100000);
  const Image split = render_test::RenderScene(WriteScene(split_dir, true, kDown), integrator, 16, 100000);
  Rgb a(0.0f), b(0.0f);
  for (size_t i = 0; i < textured.size(); ++i) {
    a += textured[i];
    b += split[i];
  }
  std::cout << integrator << ": floor mean under the textured lamp " << a.g / float(textured.size())
            << ", under the split lamp " << b.g / float(split.size()) << "\n";
  EXPECT_NEAR(a.g, b.g, 0.02f * b.g) << integrator;
}

TEST(EmissionTexture, FloorLitLikeTheSplitLampPathTracer) {
  ExpectFloorLitLikeTheSplitLamp("path");
}

TEST(EmissionTexture, FloorLitLikeTheSplitLampPhotonMap) {
  ExpectFloorLitLikeTheSplitLamp("photonmap");
}

}  // namespace
}  // namespace pf
