// Image textures (common/scene/texture.h, surface_material.h, the OBJ and glTF loaders' texture
// paths) against hand-computed texels and an analytic render: lookups at texel centres, between
// them and across each wrap mode; PNG codes decoded by the sRGB curve; OBJ's v flipped to glTF's
// convention; a textured plane under a uniform sky of radiance L renders ρ(uv)·L per quadrant
// with the path tracer and the photon map; a missing or corrupt texture is an error naming the
// file and the element; bundles ship the texture an .mtl names.
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/image/image_file.h"
#include "common/photon/photon_maps.h"
#include "common/render/integrator_factory.h"
#include "common/render/job_render_settings.h"
#include "common/render/render_settings_table.h"
#include "common/render/renderer.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_bundle.h"
#include "common/scene/scene_loader.h"
#include "common/scene/surface_material.h"
#include "common/scene/texture.h"
#include "tests/common/scene_render_util.h"

namespace pf {
namespace {

namespace fs = std::filesystem;

// A fresh folder under the test's temporary directory.
fs::path TempDir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("pf_texture_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void WriteText(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// An 8-bit RGB PNG of `w` x `h` from row-major codes (3 per pixel, top row first).
void WritePng(const fs::path& path, int w, int h, const std::vector<unsigned char>& rgb) {
  ASSERT_EQ(rgb.size(), size_t(w) * h * 3);
  ASSERT_NE(stbi_write_png(path.string().c_str(), w, h, 3, rgb.data(), w * 3), 0);
}

// A 2 x 2 texture of known linear texels.
Texture TwoByTwo(TextureWrap wrap) {
  auto image = std::make_shared<Image>(2, 2);
  image->at(0, 0) = Rgb(1.0f, 0.0f, 0.0f);  // top-left
  image->at(1, 0) = Rgb(0.0f, 1.0f, 0.0f);  // top-right
  image->at(0, 1) = Rgb(0.0f, 0.0f, 1.0f);  // bottom-left
  image->at(1, 1) = Rgb(1.0f, 1.0f, 1.0f);  // bottom-right
  Texture t;
  t.image = image;
  t.wrap_u = t.wrap_v = wrap;
  return t;
}

void ExpectRgbNear(const Rgb& a, const Rgb& b, float tolerance) {
  EXPECT_NEAR(a.r, b.r, tolerance);
  EXPECT_NEAR(a.g, b.g, tolerance);
  EXPECT_NEAR(a.b, b.b, tolerance);
}

TEST(Texture, TexelCentresReadTheirTexelAndUvOriginIsTheTopLeft) {
  const Texture t = TwoByTwo(TextureWrap::kRepeat);
  ExpectRgbNear(t.Lookup({0.25f, 0.25f}), Rgb(1, 0, 0), 1e-6f);
  ExpectRgbNear(t.Lookup({0.75f, 0.25f}), Rgb(0, 1, 0), 1e-6f);
  ExpectRgbNear(t.Lookup({0.25f, 0.75f}), Rgb(0, 0, 1), 1e-6f);
  ExpectRgbNear(t.Lookup({0.75f, 0.75f}), Rgb(1, 1, 1), 1e-6f);
}

TEST(Texture, BilinearBetweenCentres) {
  const Texture t = TwoByTwo(TextureWrap::kClampToEdge);
  // Halfway between the top two centres: their mean; the image centre: the mean of all four.
  ExpectRgbNear(t.Lookup({0.5f, 0.25f}), Rgb(0.5f, 0.5f, 0.0f), 1e-6f);
  ExpectRgbNear(t.Lookup({0.5f, 0.5f}), Rgb(0.5f, 0.5f, 0.5f), 1e-6f);
  // A quarter of the way from the top-left centre to the top-right one.
  ExpectRgbNear(t.Lookup({0.375f, 0.25f}), Rgb(0.75f, 0.25f, 0.0f), 1e-6f);
}

TEST(Texture, WrapModes) {
  // u = 0: halfway between texel −1 and texel 0 of the top row.
  // Repeat: texel −1 is texel 1 (green) → mean of red and green.
  ExpectRgbNear(TwoByTwo(TextureWrap::kRepeat).Lookup({0.0f, 0.25f}), Rgb(0.5f, 0.5f, 0.0f), 1e-6f);
  // Clamp: texel −1 is texel 0 → red.
  ExpectRgbNear(TwoByTwo(TextureWrap::kClampToEdge).Lookup({0.0f, 0.25f}), Rgb(1, 0, 0), 1e-6f);
  // Mirrored: texel −1 mirrors to texel 0 → red.
  ExpectRgbNear(TwoByTwo(TextureWrap::kMirroredRepeat).Lookup({0.0f, 0.25f}), Rgb(1, 0, 0), 1e-6f);
  // u = 1.25 (a texel centre one period on): repeat → red; mirrored → green (the mirrored copy);
  // clamp → green (the last texel).
  ExpectRgbNear(TwoByTwo(TextureWrap::kRepeat).Lookup({1.25f, 0.25f}), Rgb(1, 0, 0), 1e-6f);
  ExpectRgbNear(TwoByTwo(TextureWrap::kMirroredRepeat).Lookup({1.25f, 0.25f}), Rgb(0, 1, 0), 1e-6f);
  ExpectRgbNear(TwoByTwo(TextureWrap::kClampToEdge).Lookup({1.25f, 0.25f}), Rgb(0, 1, 0), 1e-6f);
  // Negative coordinates repeat too: −0.75 ≡ 0.25.
  ExpectRgbNear(TwoByTwo(TextureWrap::kRepeat).Lookup({-0.75f, -0.75f}), Rgb(1, 0, 0), 1e-6f);
  EXPECT_EQ(WrapTexelIndex(-1, 4, TextureWrap::kRepeat), 3);
  EXPECT_EQ(WrapTexelIndex(4, 4, TextureWrap::kMirroredRepeat), 3);
  EXPECT_EQ(WrapTexelIndex(-1, 4, TextureWrap::kMirroredRepeat), 0);
  EXPECT_EQ(WrapTexelIndex(9, 4, TextureWrap::kClampToEdge), 3);
}

TEST(Texture, PngCodesAreDecodedBySrgb) {
  const fs::path dir = TempDir("srgb");
  WritePng(dir / "t.png", 2, 1, {128, 64, 255, 0, 188, 10});
  const Image im = ReadLinearImage(dir / "t.png");
  // sRGB 128 → 0.21586, 64 → 0.05127, 188 → 0.50289 (IEC 61966-2-1).
  EXPECT_NEAR(im.at(0, 0).r, 0.21586f, 1e-4f);
  EXPECT_NEAR(im.at(0, 0).g, 0.05127f, 1e-4f);
  EXPECT_NEAR(im.at(0, 0).b, 1.0f, 1e-6f);
  EXPECT_NEAR(im.at(1, 0).g, 0.50289f, 1e-4f);
  fs::remove_all(dir);
}

TEST(Texture, GltfTexelRemapsTheMetallicRoughnessBaseColour) {
  Material m;
  m.base_color_texture = 0;
  m.metallic_roughness = MetallicRoughness{.base_color = Rgb(0.5f), .metallic = 0.0f, .roughness = 0.5f};
  Material out;
  ApplyTexels(m, MaterialTexels{.base_color = Rgb(1.0f, 0.5f, 0.0f)}, &out);
  // ρd = base·texel·(1 − metallic)·0.96 (metallic_roughness.h).
  ExpectRgbNear(out.diffuse_reflectance, Rgb(0.48f, 0.24f, 0.0f), 1e-6f);
  ExpectRgbNear(out.specular_reflectance, Rgb(0.04f), 1e-6f);
  // A metal: F0 = base·texel.
  m.metallic_roughness->metallic = 1.0f;
  ApplyTexels(m, MaterialTexels{.base_color = Rgb(1.0f, 0.5f, 0.0f)}, &out);
  ExpectRgbNear(out.specular_reflectance, Rgb(0.5f, 0.25f, 0.0f), 1e-6f);
  ExpectRgbNear(out.diffuse_reflectance, Rgb(0.0f), 1e-6f);
}

// The textured plane: a 2 x 2 m quad at z = 0 facing +z, its vt spanning the image (OBJ's v up);
// an 8 x 8 PNG in 4 x 4 quadrants, clamped (so each quadrant's inner texels read exactly its
// colour); Kd 0.8; a uniform sky of radiance 1 and nothing else.
constexpr unsigned char kQuadrant[4][3] = {{255, 255, 255}, {255, 0, 0}, {0, 0, 255}, {188, 188, 188}};

fs::path WriteTexturedPlane(const std::string& name) {
  const fs::path dir = TempDir(name);
  std::vector<unsigned char> rgb;
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      const unsigned char* c = kQuadrant[(y >= 4 ? 2 : 0) + (x >= 4 ? 1 : 0)];
      rgb.insert(rgb.end(), c, c + 3);
    }
  WritePng(dir / "checker.png", 8, 8, rgb);
  WriteText(dir / "plane.mtl", "newmtl checker\nKd 0.8 0.8 0.8\nmap_Kd -clamp on checker.png\n");
  WriteText(dir / "plane.obj",
            "mtllib plane.mtl\n"
            "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n"
            "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
            "usemtl checker\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n");
  WriteText(dir / "plane.json",
            R"({"version": 1, "geometry": "plane.obj", "environment": {"color": [1, 1, 1]},
                "cameras": [{"name": "front", "eye": [0, 0, 2.4142], "look_at": [0, 0, 0], "up": [0, 1, 0],
                             "fov": 45, "resolution": [32, 32]}]})");
  return dir;
}

TEST(Texture, ObjLoaderReadsMapKdAndFlipsV) {
  const fs::path dir = WriteTexturedPlane("obj");
  const SceneDescription s = LoadScene(dir / "plane.json");
  ASSERT_EQ(s.textures.size(), 1u);
  ASSERT_EQ(s.uvs.size(), s.positions.size());
  ASSERT_EQ(s.materials[0].base_color_texture, 0);
  EXPECT_EQ(s.textures[0].wrap_u, TextureWrap::kClampToEdge);
  // The vertex at (−1, 1, 0) has vt (0, 1): the image's top-left corner, (0, 0) in glTF's terms.
  for (size_t i = 0; i < s.positions.size(); ++i) {
    const Vec3 world = Vec3(Vec3d(s.positions[i]) + s.origin);
    EXPECT_FLOAT_EQ(s.uvs[i][0], world.x > 0 ? 1.0f : 0.0f);
    EXPECT_FLOAT_EQ(s.uvs[i][1], world.y > 0 ? 0.0f : 1.0f);
  }
  fs::remove_all(dir);
}

// Each image quadrant's inner 8 x 8 pixels: their mean against 0.8·texel·L (the plane sees only
// the sky over its hemisphere: E = π·L, radiance ρ/π·E). Measured (64 spp; 200k photons): within
// 0.15 % (path) and 0.01 % (photon map: the sky's direct light is sampled, and a lone plane gets
// no indirect light); a texture read upside down or mirrored swaps quadrants and fails by 100 %.
void ExpectQuadrantsMatch(const char* integrator) {
  const fs::path dir = WriteTexturedPlane(std::string("render_") + integrator);
  const SceneRuntime scene(LoadScene(dir / "plane.json"));
  const Image image = render_test::RenderScene(scene, integrator, 64, 200000);
  // fov 45° at distance 1/tan(22.5°): the quad fills the 32 x 32 image; quadrant q's inner pixels.
  for (int q = 0; q < 4; ++q) {
    const int x0 = (q % 2) * 16 + 4, y0 = (q / 2) * 16 + 4;
    Rgb sum(0.0f);
    for (int y = y0; y < y0 + 8; ++y)
      for (int x = x0; x < x0 + 8; ++x) sum += image.at(x, y);
    const Rgb mean = sum * (1.0f / 64.0f);
    const Rgb expected(0.8f * SrgbToLinear8(kQuadrant[q][0]), 0.8f * SrgbToLinear8(kQuadrant[q][1]),
                       0.8f * SrgbToLinear8(kQuadrant[q][2]));
    std::cout << integrator << " quadrant " << q << ": mean " << mean.r << " " << mean.g << " " << mean.b
              << ", expected " << expected.r << " " << expected.g << " " << expected.b << "\n";
    for (int c = 0; c < 3; ++c)
      EXPECT_NEAR(mean[c], expected[c], 0.004f + 0.01f * expected[c])
          << integrator << " quadrant " << q << " channel " << c;
  }
  fs::remove_all(dir);
}

TEST(Texture, TexturedPlaneUnderUniformSkyPathTracer) {
  ExpectQuadrantsMatch("path");
}

TEST(Texture, TexturedPlaneUnderUniformSkyPhotonMap) {
  ExpectQuadrantsMatch("photonmap");
}

TEST(Texture, MissingOrCorruptTextureNamesFileAndMaterial) {
  const fs::path dir = WriteTexturedPlane("missing");
  fs::remove(dir / "checker.png");
  try {
    LoadScene(dir / "plane.obj");
    ADD_FAILURE() << "a missing texture loaded";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("plane.obj"), std::string::npos) << what;
    EXPECT_NE(what.find("material 'checker'"), std::string::npos) << what;
    EXPECT_NE(what.find("checker.png"), std::string::npos) << what;
  }
  WriteText(dir / "checker.png", "not a png at all");
  try {
    LoadScene(dir / "plane.obj");
    ADD_FAILURE() << "a corrupt texture loaded";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot decode"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(Texture, TextureOutsideTheSceneFolderIsRefused) {
  const fs::path dir = WriteTexturedPlane("outside");
  WriteText(dir / "plane.mtl", "newmtl checker\nKd 0.8 0.8 0.8\nmap_Kd ../elsewhere.png\n");
  EXPECT_THROW(LoadScene(dir / "plane.obj"), InputError);
  fs::remove_all(dir);
}

TEST(Texture, BundleShipsTheTextureAnMtlNames) {
  const fs::path dir = WriteTexturedPlane("bundle");
  WritePng(dir / "preview.png", 1, 1, {1, 2, 3});  // an output next to the scene: not shipped
  const SceneBundle bundle = CollectBundle(dir / "plane.json");
  std::vector<std::string> paths;
  for (const auto& [path, content] : bundle.files) paths.push_back(path);
  EXPECT_NE(std::find(paths.begin(), paths.end(), "checker.png"), paths.end());
  EXPECT_EQ(std::find(paths.begin(), paths.end(), "preview.png"), paths.end());
  // Loaded back from a written bundle, the scene has its texture.
  const fs::path out = TempDir("bundle_out");
  WriteBundle(bundle, out);
  const SceneDescription s = LoadBundle(out, bundle.entry);
  EXPECT_EQ(s.textures.size(), 1u);
  fs::remove_all(dir);
  fs::remove_all(out);
}

}  // namespace
}  // namespace pf

namespace pf {
namespace {

const std::filesystem::path kTexturedRoom = std::filesystem::path(PF_SOURCE_DIR) / "scenes/textured-room";

// scenes/textured-room (tools/gen_textured_room.py): an external PNG (REPEAT) and one embedded in
// the .glb's buffer (CLAMP_TO_EDGE), TEXCOORD_0 read for every vertex, the factor kept beside
// the texture.
TEST(GltfTexture, GlbWithExternalAndEmbeddedImages) {
  const SceneDescription s = LoadScene(kTexturedRoom / "textured-room.glb");
  ASSERT_EQ(s.textures.size(), 2u);
  ASSERT_EQ(s.uvs.size(), s.positions.size());
  const Material& floor = s.materials[4];
  const Material& wall = s.materials[5];
  ASSERT_EQ(floor.base_color_texture, 0);
  ASSERT_EQ(wall.base_color_texture, 1);
  ASSERT_TRUE(wall.metallic_roughness.has_value());
  EXPECT_FLOAT_EQ(wall.metallic_roughness->base_color.r, 0.9f);
  EXPECT_EQ(s.textures[0].wrap_u, TextureWrap::kRepeat);
  EXPECT_EQ(s.textures[1].wrap_v, TextureWrap::kClampToEdge);
  EXPECT_EQ(s.textures[0].image->width(), 8);
  EXPECT_EQ(s.textures[1].image->width(), 16);
  // The wall's stripes left to right (texel centres of columns 2, 6, 10, 14): red, yellow, blue,
  // white, as the generator wrote them (sRGB codes 220/60/40, ...).
  const Texture& stripes = s.textures[1];
  EXPECT_NEAR(stripes.Lookup({2.5f / 16, 0.5f}).r, SrgbToLinear8(220), 1e-6f);
  EXPECT_NEAR(stripes.Lookup({6.5f / 16, 0.5f}).g, SrgbToLinear8(200), 1e-6f);
  EXPECT_NEAR(stripes.Lookup({10.5f / 16, 0.5f}).b, SrgbToLinear8(220), 1e-6f);
  // Every floor uv lies in [0, 4] (four repeats), every wall uv in [0, 1].
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    const uint32_t m = s.triangle_material[t];
    for (uint32_t v : s.triangles[t]) {
      if (m == 4) {
        EXPECT_TRUE(s.uvs[v][0] >= 0.0f && s.uvs[v][0] <= 4.0f);
      }
      if (m == 5) {
        EXPECT_TRUE(s.uvs[v][1] >= 0.0f && s.uvs[v][1] <= 1.0f);
      }
    }
  }
}

TEST(GltfTexture, MissingImageNamesTheMaterialTextureAndImage) {
  const fs::path dir = TempDir("glb_missing");
  fs::copy_file(kTexturedRoom / "textured-room.glb", dir / "textured-room.glb");
  try {
    LoadScene(dir / "textured-room.glb");
    ADD_FAILURE() << "a missing texture loaded";
  } catch (const InputError& e) {
    EXPECT_NE(
        std::string(e.what()).find("textured-room.glb: materials[4].pbrMetallicRoughness.baseColorTexture: "
                                   "textures[0]: images[0] 'checker.png'"),
        std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

TEST(GltfTexture, BundleOfAGlbShipsTheImageItNames) {
  const SceneBundle bundle = CollectBundle(kTexturedRoom / "textured-room.json");
  bool shipped = false;
  for (const auto& [path, content] : bundle.files) shipped = shipped || path == "checker.png";
  EXPECT_TRUE(shipped);
}

}  // namespace
}  // namespace pf
