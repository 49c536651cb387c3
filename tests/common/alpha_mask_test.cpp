// Alpha-mask cut-outs (scene.h Material::alpha_cutoff, surface_material.h AlphaAt, the Embree
// filter in accel/embree_scene.cpp; glTF alphaMode MASK/BLEND, OBJ map_d): the alpha channel kept
// and read linearly; glTF's mask parameters as loaded; a masked quad before a uniform sky shows the
// sky exactly through its holes and its own shading elsewhere; a floor under a black masked
// occluder lit by a sun straight down gets ρ·E/π through the holes and nothing in the occluder's
// shadow, with both integrators, and the photon walk stores the sun's flux E·A under the holes
// and no photon under the occluder.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <cmath>
#include <iostream>
#include <numbers>
#include <string>
#include <vector>

#include "common/image/image_file.h"
#include "common/photon/photon_maps.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"
#include "common/scene/surface_material.h"
#include "tests/common/gltf_test_util.h"
#include "tests/common/scene_render_util.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using gltf_test::GltfBuilder;
using ::testing::HasSubstr;

// An 8-bit PNG of `w` x `h` with `channels` codes per pixel, row-major.
void WritePng(const std::filesystem::path& path, int w, int h, int channels,
              const std::vector<unsigned char>& codes) {
  ASSERT_EQ(codes.size(), size_t(w) * h * channels);
  ASSERT_NE(stbi_write_png(path.string().c_str(), w, h, channels, codes.data(), w * channels), 0);
}

// 8 x 8: the left half's pixels (x < 4) carry `left`, the right half's `right` (channels each).
std::vector<unsigned char> Halves(const std::vector<unsigned char>& left,
                                  const std::vector<unsigned char>& right) {
  std::vector<unsigned char> codes;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x)
      codes.insert(codes.end(), x < 4 ? left.begin() : right.begin(), x < 4 ? left.end() : right.end());
  return codes;
}

TEST(AlphaMask, AlphaChannelIsKeptLinearAndFilteredLikeTheColour) {
  test_util::TempDir dir("pf_alpha_mask_test");
  WritePng(dir.path() / "rgba.png", 2, 1, 4, {128, 128, 128, 128, 0, 0, 0, 0});
  const ImageWithAlpha im = ReadImageWithAlpha(dir.path() / "rgba.png", ImageCodes::kColor);
  ASSERT_EQ(im.alpha.size(), 2u);
  EXPECT_FLOAT_EQ(im.alpha[0], 128.0f / 255.0f);              // alpha linear ...
  EXPECT_NEAR(im.rgb.at(0, 0).r, SrgbToLinear8(128), 1e-7f);  // ... colour by the sRGB curve
  EXPECT_TRUE(ReadImageWithAlpha(dir.path() / "rgba.png", ImageCodes::kData).alpha.size() == 2u);
  WritePng(dir.path() / "rgb.png", 1, 1, 3, {1, 2, 3});
  EXPECT_TRUE(ReadImageWithAlpha(dir.path() / "rgb.png", ImageCodes::kColor).alpha.empty());

  Texture t;
  t.image = std::make_shared<const Image>(im.rgb);
  t.wrap_u = t.wrap_v = TextureWrap::kClampToEdge;
  EXPECT_FLOAT_EQ(t.LookupAlpha({0.5f, 0.5f}), 1.0f);  // no alpha: opaque
  t.alpha = std::make_shared<const std::vector<float>>(im.alpha);
  EXPECT_FLOAT_EQ(t.LookupAlpha({0.25f, 0.5f}), 128.0f / 255.0f);
  EXPECT_FLOAT_EQ(t.LookupAlpha({0.75f, 0.5f}), 0.0f);
  EXPECT_FLOAT_EQ(t.LookupAlpha({0.5f, 0.5f}), 64.0f / 255.0f);  // halfway: their mean

  SceneDescription s;
  s.textures.push_back(t);
  Material m;
  m.alpha_cutoff = 0.3f;
  m.alpha_factor = 0.5f;
  m.alpha_texture = 0;
  EXPECT_FLOAT_EQ(AlphaAt(s, m, {0.25f, 0.5f}), 0.5f * 128.0f / 255.0f);
  EXPECT_TRUE(IsCutOut(s, m, {0.25f, 0.5f}));  // 0.251 < 0.3
  m.alpha_factor = 1.0f;
  EXPECT_FALSE(IsCutOut(s, m, {0.25f, 0.5f}));  // 0.502
  m.alpha_cutoff = 0.0f;
  EXPECT_FALSE(IsCutOut(s, m, {0.75f, 0.5f}));  // no mask: alpha 0 is opaque
}

// The quad of the glTF tests: 2 x 2 m at z = 0 facing +z, TEXCOORD_0 spanning the image.
// Accessors 0 POSITION, 1 NORMAL, 2 TEXCOORD_0, 3 indices.
GltfBuilder Quad() {
  GltfBuilder b;
  b.AddVec3({-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0});
  b.AddVec3({0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1});
  b.AddVec2({0, 1, 1, 1, 1, 0, 0, 0});
  b.AddIndices16({0, 1, 2, 0, 2, 3});
  return b;
}

// A material with `mode` over the quad, its base colour texture "rgba.png" (left half alpha 0,
// right half 255; colour white).
std::string MaskedQuadGltf(const std::string& material_extra) {
  return Quad().Json(R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1,"TEXCOORD_0":2},"indices":3,"material":0}]}],
      "samplers":[{"wrapS":33071,"wrapT":33071}],"textures":[{"source":0,"sampler":0}],"images":[{"uri":"rgba.png"}],
      "materials":[{"name":"leaf","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0,
                    "baseColorTexture":{"index":0}})" +
                     material_extra + "}]");
}

// `gltf` written as <name>.gltf and loaded through a manifest that adds a sky (a scene needs a light).
SceneDescription LoadUnderSky(const test_util::TempDir& dir, const std::string& name,
                              const std::string& gltf) {
  dir.Write(name + ".gltf", gltf);
  return LoadScene(dir.Write(name + ".json", R"({"version": 1, "geometry": ")" + name +
                                                 R"(.gltf", "environment": {"color": [1, 1, 1]}})"));
}

TEST(AlphaMask, GltfMaskParametersAndBlendAsMask) {
  test_util::TempDir dir("pf_alpha_mask_test");
  WritePng(dir.path() / "rgba.png", 8, 8, 4, Halves({255, 255, 255, 0}, {255, 255, 255, 255}));
  const SceneDescription mask =
      LoadUnderSky(dir, "mask", MaskedQuadGltf(R"(,"alphaMode":"MASK","alphaCutoff":0.25)"));
  const Material& m = mask.materials[0];
  EXPECT_FLOAT_EQ(m.alpha_cutoff, 0.25f);
  EXPECT_FLOAT_EQ(m.alpha_factor, 1.0f);
  EXPECT_EQ(m.alpha_texture, m.base_color_texture);
  EXPECT_THAT(::testing::PrintToString(mask.warnings), ::testing::Not(HasSubstr("alphaMode")));
  const SceneDescription blend = LoadUnderSky(dir, "blend", MaskedQuadGltf(R"(,"alphaMode":"BLEND")"));
  EXPECT_FLOAT_EQ(blend.materials[0].alpha_cutoff, 0.5f);
  EXPECT_THAT(::testing::PrintToString(blend.warnings), HasSubstr("alphaMode BLEND is rendered as MASK"));
  // OPAQUE (the default) ignores the alpha channel.
  EXPECT_FALSE(LoadUnderSky(dir, "opaque", MaskedQuadGltf("")).materials[0].HasAlphaMask());
  // A mask whose image has no alpha and whose factor is at or above the cutoff cuts nothing: dropped.
  WritePng(dir.path() / "rgba.png", 1, 1, 3, {255, 255, 255});
  EXPECT_FALSE(
      LoadUnderSky(dir, "rgb", MaskedQuadGltf(R"(,"alphaMode":"MASK")")).materials[0].HasAlphaMask());
}

// The quad, masked on its left half, before a uniform sky of radiance (0.25, 0.5, 1): camera
// rays through the holes see the sky exactly; the right half is the opaque plane (ρd = 0.48 plus
// 4 % specular: about half the sky's radiance).
void ExpectSkyThroughTheHoles(const char* integrator) {
  test_util::TempDir dir("pf_alpha_mask_test");
  WritePng(dir.path() / "rgba.png", 8, 8, 4, Halves({255, 255, 255, 0}, {255, 255, 255, 255}));
  dir.Write("quad.gltf", MaskedQuadGltf(R"(,"alphaMode":"MASK")"));
  dir.Write("quad.json", R"({"version": 1, "geometry": "quad.gltf", "environment": {"color": [0.25, 0.5, 1]},
      "cameras": [{"name": "front", "eye": [0, 0, 2.4142], "look_at": [0, 0, 0], "up": [0, 1, 0],
                   "fov": 45, "resolution": [32, 32]}]})");
  const Image image = render_test::RenderScene(dir.path() / "quad.json", integrator, 16, 20000);
  const Rgb sky(0.25f, 0.5f, 1.0f);
  Rgb right(0.0f);
  int n = 0;
  for (int y = 2; y < 30; ++y)
    for (int x = 2; x < 30; ++x) {
      if (x < 14) {
        ASSERT_EQ(image.at(x, y), sky) << integrator << " pixel " << x << ", " << y;
      } else if (x > 17) {
        right += image.at(x, y);
        ++n;
      }
    }
  right = right * (1.0f / float(n));
  std::cout << integrator << ": opaque half mean " << right.r << " " << right.g << " " << right.b << "\n";
  for (int c = 0; c < 3; ++c) {
    EXPECT_GT(right[c], 0.45f * sky[c]) << integrator;
    EXPECT_LT(right[c], 0.56f * sky[c]) << integrator;
  }
}

TEST(AlphaMask, SkySeenThroughTheHolesPathTracer) {
  ExpectSkyThroughTheHoles("path");
}

TEST(AlphaMask, SkySeenThroughTheHolesPhotonMap) {
  ExpectSkyThroughTheHoles("photonmap");
}

// A 4 x 4 m floor (Kd 0.5) at z = 0; 1 m above it a black 2 x 2 m occluder whose map_d (grey, no
// alpha) is 0 on its left half and 1 on its right; a sun straight down, E = 3 W/m². The camera
// sits between them at z = 0.5 looking down with a 90° field: it sees the floor's [−0.5, 0.5]².
std::filesystem::path WriteShadowScene(const test_util::TempDir& dir) {
  WritePng(dir.path() / "mask.png", 8, 8, 1, Halves({0}, {255}));
  dir.Write("shadow.mtl",
            "newmtl floor\nKd 0.5 0.5 0.5\n"
            "newmtl occluder\nKd 0 0 0\nmap_d -clamp on mask.png\n");
  dir.Write("shadow.obj",
            "mtllib shadow.mtl\n"
            "v -2 -2 0\nv 2 -2 0\nv 2 2 0\nv -2 2 0\n"
            "v -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
            "usemtl floor\nf 1 2 3\nf 1 3 4\n"
            "usemtl occluder\nf 5/1 6/2 7/3\nf 5/1 7/3 8/4\n");
  return dir.Write("shadow.json", R"({"version": 1, "geometry": "shadow.obj",
      "lights": [{"type": "directional", "direction": [0, 0, -1], "intensity": 3}],
      "cameras": [{"name": "down", "eye": [0, 0, 0.5], "look_at": [0, 0, 0], "up": [0, 1, 0],
                   "fov": 90, "resolution": [32, 32]}]})");
}

constexpr float kSun = 3.0f, kFloorAlbedo = 0.5f;

void ExpectLightThroughTheHoles(const char* integrator) {
  test_util::TempDir dir("pf_alpha_mask_test");
  const SceneDescription s = LoadScene(WriteShadowScene(dir));
  ASSERT_TRUE(s.materials[1].HasAlphaMask());
  EXPECT_THAT(::testing::PrintToString(s.warnings), ::testing::Not(HasSubstr("map_d")));
  const SceneRuntime scene{SceneDescription(s)};
  const Image image = render_test::RenderScene(scene, integrator, 16, 50000);
  // The seam: the filter blends the halves over 1/8 m of the occluder, 4 pixels of the floor.
  const float lit = kFloorAlbedo * kSun / std::numbers::pi_v<float>;
  Rgb left(0.0f);
  int n = 0;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      if (x < 12) {
        left += image.at(x, y);
        ++n;
      } else if (x >= 20) {
        ASSERT_EQ(image.at(x, y), Rgb(0.0f)) << integrator << " pixel " << x << ", " << y;
      }
    }
  left = left * (1.0f / float(n));
  std::cout << integrator << ": floor under the holes " << left.r << " (rho E / pi = " << lit << ")\n";
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(left[c], lit, 0.01f * lit) << integrator;
}

TEST(AlphaMask, FloorLitThroughTheHolesAndShadowedElsewherePathTracer) {
  ExpectLightThroughTheHoles("path");
}

TEST(AlphaMask, FloorLitThroughTheHolesAndShadowedElsewherePhotonMap) {
  ExpectLightThroughTheHoles("photonmap");
}

// The photon walk: the flux of the photons stored on the floor under the holes' inner part
// ([−0.9, −0.1] x [−0.9, 0.9], 1.44 m²) is E·A = 4.32 W; under the occluder's opaque half none.
TEST(AlphaMask, PhotonsPassTheHolesOnly) {
  test_util::TempDir dir("pf_alpha_mask_test");
  const SceneRuntime scene(LoadScene(WriteShadowScene(dir)));
  PhotonMapsOptions options;
  options.tracing.photons = 200000;
  const PhotonMaps maps = PhotonMaps::Build(scene.accel, scene.lights, options);
  ASSERT_TRUE(maps.global);
  Rgb under_holes(0.0f);
  int shadowed = 0, lit = 0;
  for (const Photon& p : maps.global->photons()) {
    const Vec3d w = Vec3d(p.Position()) + scene.description.origin;
    if (std::abs(w.z) > 1e-3 || std::abs(w.y) > 0.9) continue;
    if (w.x > -0.9 && w.x < -0.1) {
      under_holes += p.Power();
      ++lit;
    }
    if (w.x > 0.1 && w.x < 0.9) ++shadowed;
  }
  const float expected = kSun * 0.8f * 1.8f;
  std::cout << "photons under the holes " << lit << ", flux " << under_holes.r << " W (E A = " << expected
            << "); under the occluder " << shadowed << "\n";
  EXPECT_EQ(shadowed, 0);
  EXPECT_GT(lit, 1000);
  EXPECT_NEAR(under_holes.r, expected, 0.03f * expected);
}

}  // namespace
}  // namespace pf
