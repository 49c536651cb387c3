// Tests of OBJ/MTL loading, the scene manifest and the LoadScene dispatcher, against the
// curated scenes in scenes/ and small files written to a temporary directory.
#include "common/scene/scene_loader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iostream>
#include <set>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/scene/manifest.h"
#include "common/scene/obj_loader.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const fs::path kScenes = fs::path(PF_SOURCE_DIR) / "scenes";

const Material& FindMaterial(const SceneDescription& s, const std::string& name) {
  for (const Material& m : s.materials)
    if (m.name == name) return m;
  ADD_FAILURE() << "no material " << name;
  static const Material kNone;
  return kNone;
}

float TriangleArea(const SceneDescription& s, size_t t) {
  const auto& tri = s.triangles[t];
  return 0.5f *
         Length(Cross(s.positions[tri[1]] - s.positions[tri[0]], s.positions[tri[2]] - s.positions[tri[0]]));
}

void ExpectRgbNear(const Rgb& actual, const Rgb& expected, float tol = 1e-6f) {
  EXPECT_NEAR(actual.r, expected.r, tol);
  EXPECT_NEAR(actual.g, expected.g, tol);
  EXPECT_NEAR(actual.b, expected.b, tol);
}

// A fresh directory per test for hand-written files.
class TempDirTest : public test_util::TempDirTest {
 protected:
  fs::path Write(const std::string& name, const std::string& text) const { return tmp_.Write(name, text); }

  // Copies the Cornell box OBJ + MTL into the test folder (a manifest may refer only to files
  // in its own folder, scene_reference.h); returns the OBJ's name relative to that folder.
  std::string CopyCornellBoxHere() const {
    for (const char* f : {"CornellBox-Original.obj", "CornellBox-Original.mtl"})
      fs::copy_file(kScenes / "cornell-box" / f, dir_ / f, fs::copy_options::overwrite_existing);
    return "CornellBox-Original.obj";
  }

  // The message of the InputError that `f` throws ("" and a failure if it does not).
  template <typename F>
  static std::string ErrorOf(F&& f) {
    try {
      f();
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "expected an InputError";
    return "";
  }
};

// --- OBJ -----------------------------------------------------------------------------------

TEST(ObjLoaderTest, CornellBoxOriginal) {
  const SceneDescription s = LoadObj(kScenes / "cornell-box" / "CornellBox-Original.obj");
  // 18 quads: 5 walls, 6 + 6 box faces, 1 light.
  EXPECT_EQ(s.NumTriangles(), 36u);
  EXPECT_EQ(s.triangle_material.size(), 36u);
  EXPECT_EQ(s.triangle_light.size(), 36u);
  EXPECT_TRUE(s.normals.empty());  // the file has no `vn`
  EXPECT_TRUE(s.cameras.empty());
  ASSERT_EQ(s.num_lights, 1u);
  EXPECT_EQ(s.NumEmissiveTriangles(), 2u);

  // The light: the quad x -0.24..0.23, z -0.22..0.16 at y = 1.98, facing down.
  float light_area = 0.0f;
  for (size_t t = 0; t < s.NumTriangles(); ++t) {
    if (s.triangle_light[t] == kNoLight) continue;
    EXPECT_EQ(s.triangle_light[t], 0u);
    light_area += TriangleArea(s, t);
    const auto& tri = s.triangles[t];
    const Vec3 n =
        Cross(s.positions[tri[1]] - s.positions[tri[0]], s.positions[tri[2]] - s.positions[tri[0]]);
    EXPECT_LT(n.y, 0.0f) << "the light must face down into the box";
    EXPECT_EQ(s.materials[s.triangle_material[t]].name, "light");
  }
  EXPECT_NEAR(light_area, 0.47f * 0.38f, 1e-5f);
  ExpectRgbNear(FindMaterial(s, "light").emission, Rgb(17, 12, 4));

  const Material& red = FindMaterial(s, "leftWall");
  ExpectRgbNear(red.diffuse_reflectance, Rgb(0.63f, 0.065f, 0.05f));
  EXPECT_TRUE(red.specular_reflectance.IsBlack());
  EXPECT_EQ(red.ior, 1.0f) << "Ni is meaningless on an opaque material";
  EXPECT_FALSE(red.IsEmissive());

  const Bounds3 b = s.ComputeBounds();
  EXPECT_FLOAT_EQ(b.lo.x, -1.02f);
  EXPECT_FLOAT_EQ(b.hi.y, 1.99f);
  EXPECT_FLOAT_EQ(b.hi.z, 0.99f);
}

TEST(ObjLoaderTest, PhongExponentToWardAlpha) {
  EXPECT_FLOAT_EQ(WardAlphaFromPhongExponent(0.0f), 1.0f);
  EXPECT_FLOAT_EQ(WardAlphaFromPhongExponent(10.0f), std::sqrt(2.0f / 12.0f));
  EXPECT_FLOAT_EQ(WardAlphaFromPhongExponent(98.0f), std::sqrt(0.02f));
  EXPECT_FLOAT_EQ(WardAlphaFromPhongExponent(-5.0f), 1.0f);
  EXPECT_FLOAT_EQ(WardAlphaFromPhongExponent(999.0f), std::sqrt(2.0f / 1001.0f));
  EXPECT_EQ(WardAlphaFromPhongExponent(1000.0f), 0.0f);
  EXPECT_EQ(WardAlphaFromPhongExponent(1e6f), 0.0f);
  // Monotone: sharper highlights, smaller α.
  for (float ns = 1.0f; ns < 900.0f; ns *= 1.5f)
    EXPECT_GT(WardAlphaFromPhongExponent(ns), WardAlphaFromPhongExponent(ns * 1.5f));

  MtlParameters glossy;
  glossy.name = "glossy";
  glossy.kd = Rgb(0.5f);
  glossy.ks = Rgb(0.3f);
  glossy.ns = 48.0f;
  glossy.illum = 2;
  const Material m = MaterialFromMtl(glossy, nullptr);
  EXPECT_FLOAT_EQ(m.specular_roughness, 0.2f);  // sqrt(2/50)
  ExpectRgbNear(m.specular_reflectance, Rgb(0.3f));

  MtlParameters mirror = glossy;
  mirror.illum = 3;  // ray-traced reflection: perfect mirror whatever Ns says
  EXPECT_EQ(MaterialFromMtl(mirror, nullptr).specular_roughness, 0.0f);
  mirror.illum = 5;
  EXPECT_EQ(MaterialFromMtl(mirror, nullptr).specular_roughness, 0.0f);
}

TEST(ObjLoaderTest, TransmissionAndEnergyClamp) {
  std::vector<std::string> warnings;
  MtlParameters glass;
  glass.name = "glass";
  glass.kd = Rgb(0.2f);
  glass.tf = Rgb(0.9f, 0.95f, 1.0f);
  glass.ni = 1.5f;
  glass.illum = 7;
  Material m = MaterialFromMtl(glass, &warnings);
  ExpectRgbNear(m.specular_transmittance, Rgb(0.9f, 0.95f, 1.0f));
  EXPECT_FLOAT_EQ(m.ior, 1.5f);
  EXPECT_TRUE(m.diffuse_reflectance.IsBlack());
  EXPECT_TRUE(m.specular_reflectance.IsBlack());
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("Kd/Ks are ignored"));

  // illum 4 without Tf: clear glass.
  glass.tf = Rgb();
  glass.kd = Rgb();
  glass.illum = 4;
  warnings.clear();
  m = MaterialFromMtl(glass, &warnings);
  ExpectRgbNear(m.specular_transmittance, Rgb(1.0f));
  EXPECT_TRUE(warnings.empty());

  // Dissolve: see-through, no refraction, reflection scaled by d.
  MtlParameters dissolve;
  dissolve.name = "veil";
  dissolve.kd = Rgb(0.8f);
  dissolve.ni = 1.5f;
  dissolve.d = 0.25f;
  dissolve.illum = 2;
  m = MaterialFromMtl(dissolve, nullptr);
  ExpectRgbNear(m.specular_transmittance, Rgb(0.75f));
  ExpectRgbNear(m.diffuse_reflectance, Rgb(0.2f));
  EXPECT_EQ(m.ior, 1.0f);

  // Tf on an opaque material is ignored with a warning; white Tf silently.
  MtlParameters opaque;
  opaque.name = "opaque";
  opaque.kd = Rgb(0.5f);
  opaque.tf = Rgb(0.5f);
  opaque.illum = 2;
  warnings.clear();
  m = MaterialFromMtl(opaque, &warnings);
  EXPECT_TRUE(m.specular_transmittance.IsBlack());
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("Tf"));
  opaque.tf = Rgb(1.0f);
  warnings.clear();
  MaterialFromMtl(opaque, &warnings);
  EXPECT_TRUE(warnings.empty());

  // ρd + ρs > 1 in red only: that channel is scaled down to sum to 1.
  MtlParameters bright;
  bright.name = "bright";
  bright.kd = Rgb(0.9f, 0.5f, 0.1f);
  bright.ks = Rgb(0.6f, 0.1f, 0.1f);
  bright.ns = 100.0f;
  warnings.clear();
  m = MaterialFromMtl(bright, &warnings);
  EXPECT_NEAR(m.diffuse_reflectance.r + m.specular_reflectance.r, 1.0f, 1e-6f);
  EXPECT_NEAR(m.diffuse_reflectance.r / m.specular_reflectance.r, 1.5f, 1e-5f);
  EXPECT_FLOAT_EQ(m.diffuse_reflectance.g, 0.5f);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], HasSubstr("exceeds 1"));

  // Negative values are clamped to 0 with a warning.
  MtlParameters negative;
  negative.name = "negative";
  negative.kd = Rgb(-0.5f, 0.5f, 0.5f);
  warnings.clear();
  m = MaterialFromMtl(negative, &warnings);
  EXPECT_EQ(m.diffuse_reflectance.r, 0.0f);
  EXPECT_EQ(warnings.size(), 1u);
}

TEST(ObjLoaderTest, CornellSphereMirrorAndGlass) {
  // The bare OBJ: the left sphere is a mirror (Ns 1000); the right one's Tf is ignored
  // because the MTL has no illum 4/6/7.
  const SceneDescription bare = LoadObj(kScenes / "cornell-sphere" / "CornellBox-Sphere.obj");
  const Material& mirror = FindMaterial(bare, "leftSphere");
  ExpectRgbNear(mirror.specular_reflectance, Rgb(1.0f));
  EXPECT_EQ(mirror.specular_roughness, 0.0f);
  EXPECT_TRUE(mirror.diffuse_reflectance.IsBlack());
  EXPECT_TRUE(mirror.specular_transmittance.IsBlack());
  EXPECT_TRUE(FindMaterial(bare, "rightSphere").specular_transmittance.IsBlack());
  bool warned = false;
  for (const std::string& w : bare.warnings)
    warned = warned || (w.find("rightSphere") != std::string::npos && w.find("Tf") != std::string::npos);
  EXPECT_TRUE(warned);

  // Per-vertex normals of the spheres are used (unit length).
  ASSERT_EQ(bare.normals.size(), bare.positions.size());
  size_t with_normal = 0;
  for (const Vec3& n : bare.normals) {
    if (LengthSquared(n) == 0.0f) continue;
    ++with_normal;
    EXPECT_NEAR(Length(n), 1.0f, 1e-5f);
  }
  EXPECT_GT(with_normal, 1000u);
  EXPECT_EQ(bare.num_lights, 1u);

  // Through the manifest, the override makes the right sphere glass.
  const SceneDescription s = LoadScene(kScenes / "cornell-sphere" / "cornell-sphere.json");
  const Material& glass = FindMaterial(s, "rightSphere");
  ExpectRgbNear(glass.specular_transmittance, Rgb(0.95f));
  EXPECT_FLOAT_EQ(glass.ior, 1.6f);
  EXPECT_TRUE(glass.diffuse_reflectance.IsBlack());
  EXPECT_TRUE(glass.specular_reflectance.IsBlack());
  EXPECT_EQ(FindMaterial(s, "leftSphere").specular_roughness, 0.0f);
  ExpectRgbNear(FindMaterial(s, "leftSphere").specular_reflectance, Rgb(1.0f));
  EXPECT_EQ(s.NumTriangles(), bare.NumTriangles());
  for (const std::string& w : s.warnings)
    EXPECT_EQ(w.find("rightSphere"), std::string::npos) << "the override supersedes: " << w;
}

using ObjErrorTest = TempDirTest;

TEST_F(ObjErrorTest, MissingFile) {
  const std::string msg = ErrorOf([&] { LoadObj(dir_ / "nope.obj"); });
  EXPECT_THAT(msg, HasSubstr("nope.obj"));
  EXPECT_THAT(msg, HasSubstr("no such file"));
}

TEST_F(ObjErrorTest, FaceWithMissingVertexNamesTheLine) {
  const fs::path p = Write("bad.obj",
                           "v 0 0 0\n"
                           "v 1 0 0\n"
                           "v 0 1 0\n"
                           "f 1 2 3\n"
                           "# comment\n"
                           "f 1 2 7\n"
                           "v 0 0 1\n");
  try {
    LoadObj(p);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, p.string());
    EXPECT_EQ(e.where().line, 6);
    EXPECT_THAT(e.what(), HasSubstr("bad.obj:6:"));
  }
}

TEST_F(ObjErrorTest, RelativeIndexBeforeStartAndMissingNormal) {
  const fs::path rel = Write("rel.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n");
  EXPECT_THAT(ErrorOf([&] { LoadObj(rel); }), HasSubstr("rel.obj:4:"));
  const fs::path quad = Write("quad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 9\n");
  EXPECT_THAT(ErrorOf([&] { LoadObj(quad); }), HasSubstr("quad.obj:5:"));
  const fs::path normal = Write("normal.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n");
  EXPECT_THAT(ErrorOf([&] { LoadObj(normal); }), HasSubstr("normal.obj:5:"));
}

TEST_F(ObjErrorTest, ZeroIndexIsATinyObjParseError) {
  const fs::path p = Write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
  const std::string msg = ErrorOf([&] { LoadObj(p); });
  EXPECT_THAT(msg, HasSubstr("zero.obj:4:"));
}

// The statements are counted before tinyobjloader stores them (scene_budget.h): a file beyond a
// budget is refused at the line where the count crosses it; within the budgets the counts bound
// what is loaded.
TEST_F(ObjErrorTest, StatementsBeyondABudgetAreRefusedAtTheirLine) {
  const fs::path p = Write("budget.obj",
                           "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\n"
                           "f 1 2 3 4\n"    // 2 triangles
                           "f 1 2 3 4\n");  // 4
  SceneBudget budget;
  budget.max_triangles = 3;
  EXPECT_THAT(ErrorOf([&] { LoadObj(p, {}, budget); }),
              HasSubstr("budget.obj:7: expands to up to 4 triangles, more than the budget of 3 "
                        "(SceneBudget::max_triangles"));
  budget = SceneBudget{};
  budget.max_vertices = 4;  // v and vn count: tinyobjloader stores both
  EXPECT_THAT(ErrorOf([&] { LoadObj(p, {}, budget); }),
              HasSubstr("budget.obj:5: expands to up to 5 vertices, more than the budget of 4"));
  SceneExpansion counts;
  const SceneDescription s =
      LoadObj(kScenes / "cornell-box" / "CornellBox-Original.obj", {}, SceneBudget{}, &counts);
  EXPECT_EQ(counts.triangles, s.NumTriangles());  // quads and triangles, none degenerate
  EXPECT_GE(counts.vertices, s.positions.size());
}

TEST_F(ObjErrorTest, MissingMtlIsAWarningAndFacesGetTheDefault) {
  const fs::path p = Write("nomtl.obj",
                           "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                           "usemtl red\nf 1 2 3\n");
  const SceneDescription s = LoadObj(p);
  ASSERT_EQ(s.NumTriangles(), 1u);
  const Material& m = s.materials[s.triangle_material[0]];
  EXPECT_EQ(m.name, "(default)");
  ExpectRgbNear(m.diffuse_reflectance, Rgb(0.8f));
  EXPECT_EQ(s.num_lights, 0u);
  EXPECT_FALSE(s.warnings.empty());
}

TEST_F(ObjErrorTest, EachEmissiveGroupIsOneLight) {
  Write("lights.mtl", "newmtl lamp\nKe 2 2 2\nnewmtl wall\nKd 0.5 0.5 0.5\n");
  const fs::path p = Write("lights.obj",
                           "mtllib lights.mtl\n"
                           "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                           "v 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                           "g a\nusemtl lamp\nf 1 2 3 4\nusemtl wall\nf 5 6 7\n"
                           "g b\nusemtl lamp\nf 5 6 7 8\n"
                           "g c\nusemtl wall\nf 1 2 3\n");
  const SceneDescription s = LoadObj(p);
  EXPECT_EQ(s.NumTriangles(), 6u);
  EXPECT_EQ(s.num_lights, 2u);
  EXPECT_EQ(s.NumEmissiveTriangles(), 4u);
  std::set<uint32_t> ids(s.triangle_light.begin(), s.triangle_light.end());
  EXPECT_EQ(ids, (std::set<uint32_t>{0u, 1u, kNoLight}));
  EXPECT_EQ(s.triangle_light[0], 0u);
  EXPECT_EQ(s.triangle_light[1], 0u);
}

// --- Manifest ------------------------------------------------------------------------------

using ManifestTest = TempDirTest;

// LoadManifest(p) throws an InputError at line `line` whose message contains `text`.
void ExpectManifestErrorAt(const fs::path& p, int line, const std::string& text) {
  try {
    LoadManifest(p);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().line, line);
    EXPECT_THAT(e.what(), HasSubstr(text));
  }
}

TEST_F(ManifestTest, ParsesEveryKey) {
  const fs::path p = Write("m.json", R"({
    "version": 1,
    "name": "demo",
    "geometry": "sub/box.obj",
    "scale": 0.01,
    "cameras": [
      {"name": "main", "eye": [0, 1, 3.4], "look_at": [0, 1, 0], "up": [0, 1, 0],
       "fov": 39.3, "resolution": [640, 480]},
      {"eye": [1, 2, 3], "look_at": [0, 0, 0]}
    ],
    "settings": {"spp": 64, "photons": 2e5, "estimator": "grid", "adaptive": true,
                 "levels": [1, 2]},
    "materials": {"glass": {"kind": "glass", "ior": 1.5, "transmission": [0.9, 0.9, 1]},
                  "paint": {"kind": "glossy", "roughness": 0.1, "specular": 0.04}},
    "notes": ["line one", "line two"],
    "colour": "blue"
  })");
  const SceneManifest m = LoadManifest(p);
  EXPECT_EQ(m.name, "demo");
  EXPECT_EQ(m.geometry, (dir_ / "sub" / "box.obj").lexically_normal());
  EXPECT_DOUBLE_EQ(m.scale, 0.01);
  ASSERT_EQ(m.cameras.size(), 2u);
  EXPECT_EQ(m.cameras[0].name, "main");
  EXPECT_EQ(m.cameras[0].eye, Vec3d(0, 1, 3.4));  // world points stay in double (scene_frame.h)
  EXPECT_FLOAT_EQ(m.cameras[0].vfov_degrees, 39.3f);
  EXPECT_EQ(m.cameras[0].width, 640);
  EXPECT_EQ(m.cameras[0].height, 480);
  EXPECT_EQ(m.cameras[1].name, "camera1");
  EXPECT_EQ(m.cameras[1].up, Vec3(0, 1, 0));
  EXPECT_EQ(m.cameras[1].width, 512);
  EXPECT_EQ(std::get<double>(m.settings.at("spp")), 64.0);
  EXPECT_EQ(std::get<double>(m.settings.at("photons")), 200000.0);
  EXPECT_EQ(std::get<std::string>(m.settings.at("estimator")), "grid");
  EXPECT_EQ(std::get<std::string>(m.settings.at("adaptive")), "true");
  EXPECT_EQ(std::get<std::string>(m.settings.at("levels")), "[1,2]");
  ASSERT_EQ(m.materials.size(), 2u);
  EXPECT_EQ(m.materials.at("glass").kind, MaterialOverride::Kind::kGlass);
  EXPECT_FLOAT_EQ(*m.materials.at("glass").ior, 1.5f);
  EXPECT_EQ(*m.materials.at("paint").specular, Rgb(0.04f));
  EXPECT_EQ(m.notes, "line one\nline two");
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_THAT(m.warnings[0], HasSubstr("'colour'"));
}

TEST_F(ManifestTest, DefaultsAndAbsoluteGeometry) {
  const fs::path p = Write("just-geometry.json", R"({"geometry": "/data/x.mgf"})");
  const SceneManifest m = LoadManifest(p);
  EXPECT_EQ(m.name, "just-geometry");
  EXPECT_EQ(m.geometry, fs::path("/data/x.mgf"));
  EXPECT_EQ(m.scale, 1.0);
  EXPECT_TRUE(m.cameras.empty());
  EXPECT_TRUE(m.warnings.empty());
}

TEST_F(ManifestTest, EachMalformedKeyIsNamed) {
  const std::string cam = R"("eye": [0, 0, 1], "look_at": [0, 0, 0])";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({})", "key 'geometry': missing"},
      {R"({"geometry": 3})", "key 'geometry': expected a string"},
      {R"({"geometry": ""})", "key 'geometry'"},
      {R"({"geometry": "a.obj", "name": 7})", "key 'name'"},
      {R"({"geometry": "a.obj", "version": 2})", "key 'version'"},
      {R"({"geometry": "a.obj", "scale": -1})", "key 'scale': expected a number > 0"},
      {R"({"geometry": "a.obj", "scale": "big"})", "key 'scale': expected a number"},
      {R"({"geometry": "a.obj", "cameras": {}})", "key 'cameras'"},
      {R"({"geometry": "a.obj", "cameras": [3]})", "key 'cameras[0]': expected an object"},
      {R"({"geometry": "a.obj", "cameras": [{"look_at": [0, 0, 0]}]})", "key 'cameras[0].eye': missing"},
      {R"({"geometry": "a.obj", "cameras": [{"eye": [0, 1], "look_at": [0, 0, 0]}]})",
       "key 'cameras[0].eye': expected 3 numbers"},
      {R"({"geometry": "a.obj", "cameras": [{"eye": [0, 1, "x"], "look_at": [0, 0, 0]}]})",
       "key 'cameras[0].eye': expected 3 numbers"},
      {R"({"geometry": "a.obj", "cameras": [{"eye": [0, 1, 1e300], "look_at": [0, 0, 0]}]})",
       "key 'cameras[0].eye'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(}, {"eye": [1, 1, 1], "look_at": 5}]})",
       "key 'cameras[1].look_at': expected 3 numbers"},
      {R"({"geometry": "a.obj", "cameras": [{"eye": [1, 1, 1], "look_at": [1, 1, 1]}]})",
       "key 'cameras[0].look_at': must differ from eye"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "up": [0, 0, 2]}]})", "key 'cameras[0].up'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "fov": 180}]})", "key 'cameras[0].fov'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "fov": "wide"}]})",
       "key 'cameras[0].fov': expected a number"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "resolution": [0, 10]}]})",
       "key 'cameras[0].resolution'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "resolution": [1.5, 10]}]})",
       "key 'cameras[0].resolution'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "resolution": [100000, 10]}]})",
       "key 'cameras[0].resolution'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "name": ""}]})", "key 'cameras[0].name'"},
      {R"({"geometry": "a.obj", "cameras": [{)" + cam + R"(, "name": "a"}, {)" + cam + R"(, "name": "a"}]})",
       "key 'cameras[1].name': duplicate"},
      {R"({"geometry": "a.obj", "settings": [1]})", "key 'settings'"},
      {R"({"geometry": "a.obj", "materials": []})", "key 'materials'"},
      {R"({"geometry": "a.obj", "materials": {"x": 1}})", "key 'materials.x'"},
      {R"({"geometry": "a.obj", "materials": {"x": {"kind": "velvet"}}})", "key 'materials.x.kind'"},
      {R"({"geometry": "a.obj", "materials": {"x": {"diffuse": [1, 2]}}})", "key 'materials.x.diffuse'"},
      {R"({"geometry": "a.obj", "materials": {"x": {"emission": [1, -2, 0]}}})",
       "key 'materials.x.emission'"},
      {R"({"geometry": "a.obj", "materials": {"x": {"ior": 0}}})", "key 'materials.x.ior'"},
      {R"({"geometry": "a.obj", "materials": {"x": {"roughness": -1}}})", "key 'materials.x.roughness'"},
      {R"({"geometry": "a.obj", "materials": {"x": {"kind": "glossy"}}})", "key 'materials.x.roughness'"},
      {R"({"geometry": "a.obj", "notes": 5})", "key 'notes'"},
      {R"({"geometry": "a.obj", "notes": ["a", 5]})", "key 'notes[1]'"},
      {R"([1, 2])", "JSON object"},
  };
  for (const auto& [text, expected] : cases) {
    const fs::path p = Write("bad.json", text);
    const std::string msg = ErrorOf([&] { LoadManifest(p); });
    EXPECT_THAT(msg, HasSubstr(expected)) << text;
    EXPECT_EQ(msg.rfind(p.string() + ": ", 0), 0u) << "message must start with the file: " << msg;
  }
}

TEST_F(ManifestTest, SyntaxErrorsCarryTheLine) {
  const fs::path p = Write("syntax.json", "{\n  \"geometry\": \"a.obj\",\n  \"scale\": ,\n}\n");
  ExpectManifestErrorAt(p, 3, "syntax.json:3: invalid JSON");
  EXPECT_THAT(ErrorOf([&] { LoadManifest(dir_ / "absent.json"); }), HasSubstr("no such file"));
}

// Found by tests/fuzz/manifest_fuzz: a number too large for a double is not a parse_error but an
// out_of_range from nlohmann, and used to escape ParseManifest and terminate the process.
TEST_F(ManifestTest, NumberOverflowIsAnInputErrorWithTheLine) {
  const fs::path p = Write("overflow.json", "{\n  \"geometry\": \"a.obj\",\n  \"scale\": 1.1E11111\n}\n");
  ExpectManifestErrorAt(p, 3, "overflow.json:3: invalid JSON: number overflow");
}

// --- LoadScene: dispatch, scale, overrides ------------------------------------------------------

using LoadSceneTest = TempDirTest;

TEST_F(LoadSceneTest, DispatchErrors) {
  const std::string msg = ErrorOf([&] { LoadScene(Write("model.ply", "ply\n")); });
  EXPECT_THAT(msg, HasSubstr("'.ply'"));
  EXPECT_THAT(msg, HasSubstr(".json"));
  EXPECT_THAT(msg, HasSubstr(".mgf"));
  EXPECT_THAT(msg, HasSubstr(".obj"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(dir_ / "noext"); }), HasSubstr("supported"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(dir_ / "absent.obj"); }), HasSubstr("no such file"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(dir_ / "absent.json"); }), HasSubstr("no such file"));

  EXPECT_THAT(ErrorOf([&] { LoadScene(Write("ply.json", R"({"geometry": "m.ply"})")); }),
              HasSubstr("key 'geometry'"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(Write("nested.json", R"({"geometry": "x.json"})")); }),
              HasSubstr("key 'geometry'"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(Write("gone.json", R"({"geometry": "gone.obj"})")); }),
              HasSubstr("key 'geometry': file"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(kScenes / "cornell-box" / "CornellBox-Original.obj", -2.0); }),
              HasSubstr("scale"));
}

TEST_F(LoadSceneTest, ExtensionIsCaseInsensitive) {
  fs::copy_file(kScenes / "cornell-box" / "CornellBox-Original.mtl", dir_ / "CornellBox-Original.mtl");
  fs::copy_file(kScenes / "cornell-box" / "CornellBox-Original.obj", dir_ / "BOX.OBJ");
  const SceneDescription s = LoadScene(dir_ / "BOX.OBJ");
  EXPECT_EQ(s.NumTriangles(), 36u);
  EXPECT_EQ(s.num_lights, 1u);
}

TEST_F(LoadSceneTest, ManifestAttachesCamerasAndScales) {
  const fs::path manifest = kScenes / "cornell-box" / "cornell-box.json";
  const SceneDescription base = LoadObj(kScenes / "cornell-box" / "CornellBox-Original.obj");
  const SceneDescription s = LoadScene(manifest);
  EXPECT_EQ(s.source, manifest.string());
  ASSERT_EQ(s.cameras.size(), 1u);
  EXPECT_EQ(s.cameras[0].name, "main");
  EXPECT_EQ(s.NumTriangles(), base.NumTriangles());

  const SceneDescription doubled = LoadScene(manifest, 2.0);
  ASSERT_EQ(doubled.positions.size(), base.positions.size());
  for (size_t i = 0; i < base.positions.size(); ++i)
    EXPECT_EQ(doubled.positions[i], base.positions[i] * 2.0f);
  EXPECT_EQ(doubled.cameras[0].eye, s.cameras[0].eye * 2.0f);
  EXPECT_EQ(doubled.cameras[0].look_at, s.cameras[0].look_at * 2.0f);
  EXPECT_EQ(doubled.cameras[0].up, s.cameras[0].up);
  ExpectRgbNear(FindMaterial(doubled, "light").emission, Rgb(17, 12, 4));

  // The manifest's own "scale", and the override winning.
  const std::string obj = CopyCornellBoxHere();
  const fs::path half = Write("half.json", R"({"geometry": ")" + obj + R"(", "scale": 0.5,
      "cameras": [{"eye": [0, 1, 4], "look_at": [0, 1, 0]}]})");
  const SceneDescription h = LoadScene(half);
  EXPECT_FLOAT_EQ(h.ComputeBounds().hi.y, 0.5f * 1.99f);
  EXPECT_EQ(h.cameras[0].eye, Vec3(0, 0.5f, 2.0f));
  EXPECT_FLOAT_EQ(LoadScene(half, 3.0).ComputeBounds().hi.y, 3.0f * 1.99f);

  // A bare file with a scale override.
  const SceneDescription bare = LoadScene(kScenes / "cornell-box" / "CornellBox-Original.obj", 10);
  EXPECT_FLOAT_EQ(bare.ComputeBounds().hi.y, 19.9f);
}

// A manifest "scale" (or a scale override) that would make world coordinates overflow a float,
// collapse the scene, or make a camera degenerate is an InputError naming the manifest (and the
// key's line) and the field, never a scene with Inf/NaN vertices or cameras. Before, "scale": 1e39
// loaded: vertices ±Inf or NaN (0 × Inf), the camera's eye (-nan, inf, inf) (`pf info`).
TEST_F(LoadSceneTest, ScalesThatBreakCoordinatesAreErrorsNamingTheField) {
  const std::string obj = CopyCornellBoxHere();
  auto manifest = [&](const std::string& name, const std::string& scale, const std::string& eye) {
    return Write(name, "{\n  \"geometry\": \"" + obj + "\",\n  \"scale\": " + scale +
                           ",\n  \"cameras\": [{\"eye\": " + eye + ", \"look_at\": [0, 1, 0]}]\n}\n");
  };
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("big.json", "1e39", "[0, 1, 4]")); }),
              HasSubstr("big.json:3: key 'scale': 1e+39 makes vertex coordinates overflow a 32-bit float "
                        "(largest |coordinate| 1.99 x scale = 1.99e+39)"));
  // The vertices fit (1.99e36), the camera 1000 m away does not.
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("far.json", "1e36", "[0, 1, 1000]")); }),
              HasSubstr("far.json:3: key 'scale': 1e+36 makes cameras[0].eye overflow a 32-bit float"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("tiny.json", "1e-300", "[0, 1, 4]")); }),
              HasSubstr("tiny.json:3: key 'scale': 1e-300 is below the smallest normal float"));
  // Eye and look-at 1e-7 apart, scaled by 1e-30: their difference squared underflows.
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("close.json", "1e-30", "[0, 1, 1e-7]")); }),
              HasSubstr("close.json:3: key 'scale': 1e-30 makes cameras[0].look_at coincide with its eye"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("ok.json", "1e-30", "[0, 1, 1e-7]"), 1e39); }),
              HasSubstr("ok.json: scale override: 1e+39 makes vertex coordinates overflow"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(dir_ / obj, 1e39); }),
              HasSubstr("CornellBox-Original.obj: scale override: 1e+39 makes vertex coordinates overflow"));
  // JSON has no NaN: a NaN camera is a syntax error with its line; 1e39 is not a finite float.
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("nan.json", "1", "[NaN, 1, 4]")); }),
              HasSubstr("nan.json:4:"));
  EXPECT_THAT(ErrorOf([&] { LoadScene(manifest("inf.json", "1", "[1e39, 1, 4]")); }),
              HasSubstr("key 'cameras[0].eye': expected 3 finite numbers"));
  // The largest scale that fits still loads, every coordinate finite.
  const SceneDescription s = LoadScene(manifest("fits.json", "1e38", "[0, 1, 1]"));
  for (const Vec3& p : s.positions) ASSERT_TRUE(IsFinite(p));
}

// Coordinates far from the origin stay in double until the scene's frame is chosen
// (scene_frame.h): the OBJ's vertices at 1e6 + decimals are stored relative to the centre of their
// bounds, each the exact point minus that origin, rounded once; the manifest's camera stays in
// world coordinates (double) and the default camera is the untranslated one's, moved.
TEST_F(LoadSceneTest, FarObjCoordinatesAreStoredInTheScenesFrame) {
  const std::string text =
      "v 1000000.13 -2000000.27 3000000.39\nv 1000001.87 -2000000.27 3000000.39\n"
      "v 1000001.87 -1999999.61 3000000.39\nv 1000000.13 -1999999.61 3000000.39\nf 1 2 3 4\n";
  Write("far.obj", text);
  const fs::path p =
      Write("far.json", R"({"geometry": "far.obj", "cameras": [{"eye": [1000001, -2000000, 3000003.9],
      "look_at": [1000001, -2000000, 3000000.39]}], "lights": [{"type": "directional", "direction": [0, 0, -1]}]})");
  const SceneDescription s = LoadScene(p);
  const Vec3d centre(1000001.0, -1999999.94, 3000000.39);
  EXPECT_NEAR(s.origin.x, centre.x, 1e-9);
  EXPECT_NEAR(s.origin.y, centre.y, 1e-9);
  EXPECT_NEAR(s.origin.z, centre.z, 1e-9);
  const Vec3 expected[] = {{-0.87f, -0.33f, 0}, {0.87f, -0.33f, 0}, {0.87f, 0.33f, 0}, {-0.87f, 0.33f, 0}};
  ASSERT_EQ(s.positions.size(), 4u);
  for (const Vec3& corner : expected) {  // in the order the triangles first use them
    bool found = false;
    for (const Vec3& p : s.positions) found = found || LengthSquared(p - corner) < 1e-12f;
    EXPECT_TRUE(found) << corner.x << " " << corner.y;
  }
  EXPECT_EQ(s.cameras[0].eye, Vec3d(1000001, -2000000, 3000003.9));
  const Vec3 eye = Camera(s.cameras[0], s.origin).eye();
  EXPECT_NEAR(eye.y, -0.06f, 1e-6f);
  EXPECT_NEAR(eye.z, 3.51f, 1e-6f);
  // The same quad around the origin: origin 0, world floats.
  Write("near.obj", "v -.87 -.33 0\nv .87 -.33 0\nv .87 .33 0\nv -.87 .33 0\nf 1 2 3 4\n");
  // (Through the OBJ loader: without a light, LoadScene refuses a bare file.)
  const SceneDescription near = LoadObj(dir_ / "near.obj");
  EXPECT_EQ(near.origin, Vec3d());
  EXPECT_EQ(near.positions[0], Vec3(-0.87f, -0.33f, 0.0f));
  const CameraSpec far_default = DefaultCamera(LoadObj(dir_ / "far.obj")), near_default = DefaultCamera(near);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(far_default.eye[k] - centre[k], near_default.eye[k], 1e-6);
    EXPECT_NEAR(far_default.look_at[k] - centre[k], near_default.look_at[k], 1e-6);
  }
}

TEST_F(LoadSceneTest, MaterialOverrides) {
  const std::string obj = CopyCornellBoxHere();
  const fs::path p = Write("o.json", R"({"geometry": ")" + obj + R"(", "materials": {
      "tallBox": {"kind": "mirror"},
      "shortBox": {"kind": "glass", "ior": 1.33},
      "floor": {"kind": "glossy", "specular": 0.5, "roughness": 0.2},
      "light": {"emission": [10, 10, 10]}}})");
  const SceneDescription s = LoadScene(p);
  const Material& tall = FindMaterial(s, "tallBox");
  ExpectRgbNear(tall.specular_reflectance, Rgb(1.0f));
  EXPECT_TRUE(tall.diffuse_reflectance.IsBlack());
  EXPECT_EQ(tall.specular_roughness, 0.0f);
  const Material& short_box = FindMaterial(s, "shortBox");
  ExpectRgbNear(short_box.specular_transmittance, Rgb(1.0f));
  EXPECT_FLOAT_EQ(short_box.ior, 1.33f);
  EXPECT_TRUE(short_box.diffuse_reflectance.IsBlack());
  const Material& floor = FindMaterial(s, "floor");
  EXPECT_FLOAT_EQ(floor.specular_roughness, 0.2f);
  // ρd 0.725 + ρs 0.5 > 1: clamped, with a warning.
  EXPECT_NEAR(floor.diffuse_reflectance.r + floor.specular_reflectance.r, 1.0f, 1e-6f);
  bool warned = false;
  for (const std::string& w : s.warnings) warned = warned || w.find("materials.floor") != std::string::npos;
  EXPECT_TRUE(warned);
  ExpectRgbNear(FindMaterial(s, "light").emission, Rgb(10.0f));
  EXPECT_EQ(s.num_lights, 1u);

  EXPECT_THAT(ErrorOf([&] {
                LoadScene(Write("u.json", R"({"geometry": ")" + obj +
                                              R"(", "materials": {"marble": {"kind": "mirror"}}})"));
              }),
              HasSubstr("key 'materials.marble'"));
  EXPECT_THAT(ErrorOf([&] {
                LoadScene(Write(
                    "e.json", R"({"geometry": ")" + obj + R"(", "materials": {"floor": {"emission": 1}}})"));
              }),
              HasSubstr("key 'materials.floor.emission'"));
}

// --- Default camera ----------------------------------------------------------------------

TEST(DefaultCameraTest, FramesTheCornellBoxFromTheOpenSide) {
  const SceneDescription s = LoadObj(kScenes / "cornell-box" / "CornellBox-Original.obj");
  const CameraSpec cam = DefaultCamera(s);
  const Bounds3 b = s.ComputeBounds();
  EXPECT_GT(cam.eye.z, b.hi.z);
  EXPECT_EQ(cam.look_at, b.Center());
  EXPECT_EQ(cam.up, Vec3(0, 1, 0));
  // Every corner of the bounding box is inside the field of view.
  const Vec3 f = Normalize(Vec3(cam.look_at - cam.eye));
  const Vec3 r = Normalize(Cross(f, cam.up));
  const Vec3 u = Cross(r, f);
  const float tan_half = std::tan(0.5f * cam.vfov_degrees * kPi / 180.0f);
  for (int i = 0; i < 8; ++i) {
    const Vec3 corner((i & 1) ? b.hi.x : b.lo.x, (i & 2) ? b.hi.y : b.lo.y, (i & 4) ? b.hi.z : b.lo.z);
    const Vec3 d = corner - Vec3(cam.eye);
    const float depth = Dot(d, f);
    ASSERT_GT(depth, 0.0f);
    EXPECT_LE(std::abs(Dot(d, r)) / depth, tan_half);
    EXPECT_LE(std::abs(Dot(d, u)) / depth, tan_half);
  }
  // An empty scene still gets a valid camera.
  const CameraSpec empty = DefaultCamera(SceneDescription{});
  EXPECT_NE(empty.eye, empty.look_at);
}

// --- The furnace scenes ------------------------------------------------------------------

TEST(CuratedScenesTest, FurnaceIsAClosedInwardEmitterWithEnergyConservingObjects) {
  const SceneDescription s = LoadScene(kScenes / "furnace" / "furnace-objects.json");
  ASSERT_EQ(s.cameras.size(), 1u);
  EXPECT_EQ(s.cameras[0].eye, Vec3(0.0f));
  EXPECT_EQ(s.num_lights, 1u);
  const Material& wall = FindMaterial(s, "furnace_wall");
  ExpectRgbNear(wall.diffuse_reflectance, Rgb(0.8f), 1e-4f);
  ExpectRgbNear(wall.emission, Rgb(1.0f), 1e-4f);  // ed 562.345085 = 179 π
  const Material& mirror = FindMaterial(s, "furnace_mirror");
  ExpectRgbNear(mirror.specular_reflectance, Rgb(1.0f), 1e-4f);
  EXPECT_EQ(mirror.specular_roughness, 0.0f);
  const Material& glass = FindMaterial(s, "furnace_glass");
  ExpectRgbNear(glass.specular_transmittance, Rgb(1.0f), 1e-4f);
  EXPECT_FLOAT_EQ(glass.ior, 1.5f);
  size_t per_material[3] = {0, 0, 0};
  for (size_t t = 0; t < s.NumTriangles(); ++t) {
    const std::string& name = s.materials[s.triangle_material[t]].name;
    const auto& tri = s.triangles[t];
    const Vec3 centroid = (s.positions[tri[0]] + s.positions[tri[1]] + s.positions[tri[2]]) / 3.0f;
    const Vec3 n =
        Cross(s.positions[tri[1]] - s.positions[tri[0]], s.positions[tri[2]] - s.positions[tri[0]]);
    if (name == "furnace_wall") {
      ++per_material[0];
      EXPECT_LT(Dot(n, centroid), 0.0f) << "the furnace must face inward (front-side emission)";
      EXPECT_EQ(s.triangle_light[t], 0u);
    } else {
      ++per_material[name == "furnace_mirror" ? 1 : 2];
      EXPECT_EQ(s.triangle_light[t], kNoLight);
      EXPECT_LT(Length(centroid), 1.0f);
      EXPECT_GT(Length(centroid), 0.3f) << "objects keep clear of the camera at the centre";
    }
  }
  EXPECT_GT(per_material[0], 0u);
  EXPECT_GT(per_material[1], 0u);
  EXPECT_GT(per_material[2], 0u);
}

// --- Every curated scene ------------------------------------------------------------------

TEST(CuratedScenesTest, EveryManifestLoads) {
  std::vector<fs::path> manifests;
  for (const auto& entry : fs::recursive_directory_iterator(kScenes))
    if (entry.is_regular_file() && entry.path().extension() == ".json") manifests.push_back(entry.path());
  std::sort(manifests.begin(), manifests.end());
  ASSERT_GE(manifests.size(), 6u);
  for (const fs::path& p : manifests) {
    SCOPED_TRACE(p.string());
    SceneDescription s;
    ASSERT_NO_THROW(s = LoadScene(p));
    EXPECT_GT(s.NumTriangles(), 0u);
    EXPECT_GT(s.num_lights, 0u);
    ASSERT_FALSE(s.cameras.empty());
    EXPECT_EQ(s.triangle_material.size(), s.NumTriangles());
    EXPECT_EQ(s.triangle_light.size(), s.NumTriangles());
    EXPECT_TRUE(s.normals.empty() || s.normals.size() == s.positions.size());
    std::set<uint32_t> lights;
    for (size_t t = 0; t < s.NumTriangles(); ++t) {
      EXPECT_LT(s.triangle_material[t], s.materials.size());
      for (uint32_t v : s.triangles[t]) EXPECT_LT(v, s.positions.size());
      if (s.triangle_light[t] != kNoLight) {
        EXPECT_LT(s.triangle_light[t], s.num_lights);
        EXPECT_TRUE(s.materials[s.triangle_material[t]].IsEmissive());
        lights.insert(s.triangle_light[t]);
      }
    }
    EXPECT_EQ(lights.size() + s.punctual_lights.size() + (s.environment ? 1 : 0), s.num_lights)
        << "every light id is used";
    for (const Vec3& v : s.positions) ASSERT_TRUE(IsFinite(v));
    // Cameras look at something inside the scene's bounds.
    const Bounds3 b = s.ComputeBounds();
    for (const CameraSpec& c : s.cameras) {
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(c.look_at[a], b.lo[a] - 1e-3f) << c.name;
        EXPECT_LE(c.look_at[a], b.hi[a] + 1e-3f) << c.name;
      }
    }
    std::cout << "[ scene    ] " << fs::relative(p, kScenes).string() << ": " << s.NumTriangles()
              << " triangles, " << s.num_lights << " lights (" << s.NumEmissiveTriangles()
              << " emissive triangles), " << s.materials.size() << " materials, bounds [" << b.lo.x << " "
              << b.lo.y << " " << b.lo.z << "] - [" << b.hi.x << " " << b.hi.y << " " << b.hi.z << "], "
              << s.warnings.size() << " warnings\n";
  }
}

}  // namespace
}  // namespace pf
