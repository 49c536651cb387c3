// glTF 2.0 → SceneDescription (common/scene/gltf_loader.h), its materials and lights
// (gltf_materials.h, gltf_lights.h), LoadScene's dispatch and the bundle rule for glTF.
#include "common/scene/gltf_loader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "common/core/error.h"
#include "common/scene/scene_bundle.h"
#include "common/scene/scene_loader.h"
#include "tests/common/gltf_test_util.h"
#include "tests/util/input_error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using gltf_test::GltfBuilder;
using ::testing::HasSubstr;

constexpr double kSqrtHalf = 0.70710678118654752;

// One triangle (0,0,0) (1,0,0) (0,1,0) with normals +z: accessors 0 (POSITION), 1 (NORMAL),
// 2 (indices).
GltfBuilder Triangle() {
  GltfBuilder b;
  b.AddVec3({0, 0, 0, 1, 0, 0, 0, 1, 0});
  b.AddVec3({0, 0, 1, 0, 0, 1, 0, 0, 1});
  b.AddIndices16({0, 1, 2});
  return b;
}

constexpr const char* kTriangleMesh =
    R"("meshes":[{"primitives":[{"attributes":{"POSITION":0,"NORMAL":1},"indices":2,"material":0}]}])";
constexpr const char* kLamp = R"("materials":[{"name":"lamp","emissiveFactor":[1,1,1]}])";

std::string ErrorOf(const std::filesystem::path& p) {
  return testing::InputErrorOf([&] { LoadGltf(p); });
}

Vec3d World(const SceneDescription& s, uint32_t vertex) {
  return Vec3d(s.positions[vertex]) + s.origin;
}

void ExpectNear(const Vec3d& got, const Vec3d& want, double tol = 1e-5) {
  EXPECT_NEAR(got.x, want.x, tol);
  EXPECT_NEAR(got.y, want.y, tol);
  EXPECT_NEAR(got.z, want.z, tol);
}

TEST(GltfLoader, ChildOfATranslatedRotatedScaledParentLandsWhereTheMathSays) {
  test_util::TempDir dir("pf_gltf_test");
  // Parent: T(10,0,0)·Ry(90°)·S(2); child: T(1,0,0). Ry(90°) maps +x to −z.
  const std::string nodes = R"("scene":0,"scenes":[{"nodes":[0]}],"nodes":[
      {"translation":[10,0,0],"rotation":[0,)" +
                            std::to_string(kSqrtHalf) + "," + "0," + std::to_string(kSqrtHalf) +
                            R"(],"scale":[2,2,2],"children":[1]},
      {"translation":[1,0,0],"mesh":0}],)";
  const SceneDescription s =
      LoadGltf(dir.Write("scene.gltf", Triangle().Json(nodes + kTriangleMesh + "," + kLamp)));
  ASSERT_EQ(s.triangles.size(), 1u);
  const auto& t = s.triangles[0];
  ExpectNear(World(s, t[0]), {10, 0, -2});  // (0,0,0) → child (1,0,0) → scale (2,0,0) → (0,0,−2) + T
  ExpectNear(World(s, t[1]), {10, 0, -4});
  ExpectNear(World(s, t[2]), {10, 2, -2});
  // The normal +z turns to +x under Ry(90°) (uniform scale: no change of direction).
  ExpectNear(Vec3d(s.normals[t[0]]), {1, 0, 0});
  EXPECT_EQ(s.num_lights, 1u);
  EXPECT_EQ(s.triangle_light[0], 0u);
}

TEST(GltfLoader, MatrixTransformIsColumnMajor) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string nodes =
      R"("scenes":[{"nodes":[0]}],"nodes":[{"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 3,4,5,1],"mesh":0}],)";
  const SceneDescription s =
      LoadGltf(dir.Write("scene.gltf", Triangle().Json(nodes + kTriangleMesh + "," + kLamp)));
  ExpectNear(World(s, s.triangles[0][1]), {4, 4, 5});
}

TEST(GltfLoader, NormalsTransformByTheInverseTransposeAndMirrorsKeepTheFront) {
  test_util::TempDir dir("pf_gltf_test");
  GltfBuilder b;
  b.AddVec3({0, 0, 0, 1, 0, 0, 0, 1, 0});
  b.AddVec3({1, 1, 0, 1, 1, 0, 1, 1, 0});  // (1,1,0)/√2 after normalising
  b.AddIndices16({0, 1, 2});
  const std::string nodes = R"("scenes":[{"nodes":[0,1]}],"nodes":[{"scale":[2,1,1],"mesh":0},
      {"scale":[-1,1,1],"mesh":0}],)";
  const SceneDescription s = LoadGltf(dir.Write("scene.gltf", b.Json(nodes + kTriangleMesh + "," + kLamp)));
  ASSERT_EQ(s.triangles.size(), 2u);
  // Scale (2,1,1): M⁻ᵀ = diag(1/2, 1, 1), so (1,1,0) → (0.5,1,0), normalised.
  ExpectNear(Vec3d(s.normals[s.triangles[0][0]]), Vec3d(0.5, 1, 0) / std::sqrt(1.25));
  // Mirror in x: the normal's x flips, and the winding is reversed so that the geometric
  // normal (the emitting front) still agrees with the shading normal's +z... here with +z.
  ExpectNear(Vec3d(s.normals[s.triangles[1][0]]), Vec3d(-1, 1, 0) * kSqrtHalf);
  const auto& t = s.triangles[1];
  const Vec3 e = Cross(s.positions[t[1]] - s.positions[t[0]], s.positions[t[2]] - s.positions[t[0]]);
  EXPECT_GT(e.z, 0.0f);
}

TEST(GltfLoader, FirstPerspectiveCameraInNodeOrder) {
  test_util::TempDir dir("pf_gltf_test");
  // Node 1 (orthographic) comes first: warned about and skipped; node 2 rotates its camera by
  // 90° about +y, so it looks down −x.
  const std::string rest = R"("scenes":[{"nodes":[0,1,2]}],"nodes":[{"mesh":0},{"camera":0},
      {"camera":1,"translation":[0,1,5],"rotation":[0,)" +
                           std::to_string(kSqrtHalf) + ",0," + std::to_string(kSqrtHalf) +
                           R"(]}],
      "cameras":[{"type":"orthographic","orthographic":{"xmag":1,"ymag":1,"znear":0.1,"zfar":10}},
                 {"name":"shot","type":"perspective","perspective":{"yfov":0.5,"aspectRatio":1.5,"znear":0.1}}],)";
  const SceneDescription s =
      LoadGltf(dir.Write("scene.gltf", Triangle().Json(rest + kTriangleMesh + "," + kLamp)));
  ASSERT_EQ(s.cameras.size(), 1u);
  const CameraSpec& c = s.cameras[0];
  EXPECT_EQ(c.name, "shot");
  ExpectNear(c.eye, {0, 1, 5});
  ExpectNear(Normalize(c.look_at - c.eye), {-1, 0, 0});
  // It looks at the point of its axis nearest the scene's centre (the triangle's, (1/2, 1/2, 0)),
  // clamped to 1 m ahead: here the centre is behind it.
  ExpectNear(c.look_at, {-1, 1, 5});
  ExpectNear(Vec3d(c.up), {0, 1, 0});
  EXPECT_NEAR(c.vfov_degrees, 0.5 * 180.0 / 3.14159265358979, 1e-4);
  EXPECT_EQ(c.width, 768);
  EXPECT_EQ(c.height, 512);
  EXPECT_THAT(::testing::PrintToString(s.warnings),
              HasSubstr("cameras[0]: a orthographic camera is not supported"));
}

TEST(GltfLoader, NoCameraLeavesTheDefault) {
  test_util::TempDir dir("pf_gltf_test");
  const SceneDescription s =
      LoadGltf(dir.Write("scene.gltf", Triangle().Json(R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" +
                                                       std::string(kTriangleMesh) + "," + kLamp)));
  EXPECT_TRUE(s.cameras.empty());
}

TEST(GltfLoader, PunctualLightsInRadiometricUnitsAndSpotAngles) {
  test_util::TempDir dir("pf_gltf_test");
  // A spot at (0,3,0) turned to look down (−90° about x maps −z to −y), a point light, a sun.
  const std::string rest = R"("extensionsUsed":["KHR_lights_punctual"],
      "extensions":{"KHR_lights_punctual":{"lights":[
        {"type":"spot","color":[1,0.5,0],"intensity":683,"spot":{"innerConeAngle":0.2,"outerConeAngle":0.5}},
        {"type":"point","intensity":1366,"range":10},
        {"type":"directional","intensity":68.3}]}},
      "scenes":[{"nodes":[0,1,2,3]}],"nodes":[{"mesh":0},
        {"translation":[0,3,0],"rotation":[-)" +
                           std::to_string(kSqrtHalf) + ",0,0," + std::to_string(kSqrtHalf) +
                           R"(],"extensions":{"KHR_lights_punctual":{"light":0}}},
        {"translation":[1,2,3],"extensions":{"KHR_lights_punctual":{"light":1}}},
        {"extensions":{"KHR_lights_punctual":{"light":2}}}],)";
  const SceneDescription s =
      LoadGltf(dir.Write("scene.gltf", Triangle().Json(rest + kTriangleMesh + "," + kLamp)));
  ASSERT_EQ(s.punctual_lights.size(), 3u);
  const PunctualLight& spot = s.punctual_lights[0];
  EXPECT_EQ(spot.kind, PunctualLight::Kind::kSpot);
  EXPECT_NEAR(spot.intensity.r, 1.0f, 1e-6f);  // 683 cd / 683 lm/W = 1 W/sr
  EXPECT_NEAR(spot.intensity.g, 0.5f, 1e-6f);
  EXPECT_EQ(spot.intensity.b, 0.0f);
  ExpectNear(spot.position, {0, 3, 0});
  ExpectNear(Vec3d(spot.direction), {0, -1, 0});
  EXPECT_NEAR(spot.inner_cone_deg, 0.2 * 180 / 3.14159265358979, 1e-4);
  EXPECT_NEAR(spot.outer_cone_deg, 0.5 * 180 / 3.14159265358979, 1e-4);
  EXPECT_EQ(s.punctual_lights[1].kind, PunctualLight::Kind::kPoint);
  EXPECT_NEAR(s.punctual_lights[1].intensity.g, 2.0f, 1e-6f);
  ExpectNear(s.punctual_lights[1].position, {1, 2, 3});
  EXPECT_EQ(s.punctual_lights[2].kind, PunctualLight::Kind::kDirectional);
  EXPECT_NEAR(s.punctual_lights[2].intensity.b, 0.1f, 1e-6f);  // 68.3 lux → 0.1 W/m²
  ExpectNear(Vec3d(s.punctual_lights[2].direction), {0, 0, -1});
  // Ids follow the emitting triangle's (light 0).
  EXPECT_EQ(s.num_lights, 4u);
  EXPECT_EQ(spot.light, 1u);
  EXPECT_THAT(::testing::PrintToString(s.warnings), HasSubstr("lights[1]: range"));
}

TEST(GltfLoader, SpotConeAnglesOutOfOrderAreAnError) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string rest = R"("extensions":{"KHR_lights_punctual":{"lights":[
        {"type":"spot","spot":{"innerConeAngle":0.5,"outerConeAngle":0.4}}]}},
      "scenes":[{"nodes":[0,1]}],"nodes":[{"mesh":0},{"extensions":{"KHR_lights_punctual":{"light":0}}}],)";
  EXPECT_THAT(ErrorOf(dir.Write("scene.gltf", Triangle().Json(rest + kTriangleMesh + "," + kLamp))),
              HasSubstr("scene.gltf: KHR_lights_punctual.lights[0]: spot cone angles"));
}

// Blender's exporter writes innerConeAngle = outerConeAngle for a spot lamp without blend, which
// the specification does not allow (inner < outer): it is read as a hard-edged cone, and a band
// narrower than the manifest's kMinSpotFalloffDeg too. An outer angle of 0 (or below that limit) is
// still refused.
TEST(GltfLoader, SpotWithEqualConeAnglesIsHardEdged) {
  test_util::TempDir dir("pf_gltf_test");
  const auto load = [&](const std::string& spot) {
    const std::string rest = R"("extensions":{"KHR_lights_punctual":{"lights":[{"type":"spot","spot":)" +
                             spot +
                             R"(}]}},
      "scenes":[{"nodes":[0,1]}],"nodes":[{"mesh":0},{"extensions":{"KHR_lights_punctual":{"light":0}}}],)";
    return dir.Write("scene.gltf", Triangle().Json(rest + kTriangleMesh + "," + kLamp));
  };
  SceneDescription s = LoadGltf(load(R"({"innerConeAngle":0.5,"outerConeAngle":0.5})"));
  ASSERT_EQ(s.punctual_lights.size(), 1u);
  EXPECT_EQ(s.punctual_lights[0].inner_cone_deg, s.punctual_lights[0].outer_cone_deg);
  EXPECT_NEAR(s.punctual_lights[0].outer_cone_deg, 0.5 * 180 / 3.14159265358979, 1e-4);
  s = LoadGltf(load(R"({"innerConeAngle":0.4999,"outerConeAngle":0.5})"));
  EXPECT_EQ(s.punctual_lights[0].inner_cone_deg, s.punctual_lights[0].outer_cone_deg);
  EXPECT_THAT(ErrorOf(load(R"({"innerConeAngle":0,"outerConeAngle":0})")), HasSubstr("spot cone angles"));
  // A cone whose float cosine is 1 would carry no power: refused with the element named.
  EXPECT_THAT(ErrorOf(load(R"({"innerConeAngle":0,"outerConeAngle":0.0001})")),
              HasSubstr("scene.gltf: KHR_lights_punctual.lights[0]: outerConeAngle must be at least"));
}

TEST(GltfLoader, MaterialMapping) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string rest = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0},"material":0},{"attributes":{"POSITION":0},"material":1},
                               {"attributes":{"POSITION":0},"material":2},{"attributes":{"POSITION":0},"material":3}]}],
      "textures":[{"source":0}],"images":[{"uri":"wood.png"}],
      "materials":[
        {"name":"Wood","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.6,0.4,1],"metallicFactor":0.25,
          "roughnessFactor":0.5},"normalTexture":{"index":0}},
        {"name":"Chrome","pbrMetallicRoughness":{"metallicFactor":1,"roughnessFactor":0}},
        {"name":"Glass","doubleSided":true,"pbrMetallicRoughness":{"metallicFactor":0},
          "extensions":{"KHR_materials_transmission":{"transmissionFactor":1},"KHR_materials_ior":{"ior":1.33}}},
        {"name":"Panel","emissiveFactor":[1,0.5,0.25],
          "extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":8}}}])";
  const SceneDescription s = LoadGltf(dir.Write("scene.gltf", Triangle().Json(rest)));
  ASSERT_EQ(s.materials.size(), 4u);
  // metallic_roughness.h: F0 = 0.04·(1 − m) + b·m, ρd = b·(1 − m)·0.96, GGX roughness r.
  const Material& wood = s.materials[0];
  EXPECT_EQ(wood.microfacet, Material::Microfacet::kConductor);
  EXPECT_NEAR(wood.diffuse_reflectance.r, 0.8f * 0.75f * 0.96f, 1e-6f);
  EXPECT_NEAR(wood.specular_reflectance.g, 0.04f * 0.75f + 0.6f * 0.25f, 1e-6f);
  EXPECT_NEAR(wood.microfacet_roughness, 0.5f, 1e-6f);
  EXPECT_TRUE(wood.one_sided);
  const Material& chrome = s.materials[1];
  EXPECT_EQ(chrome.diffuse_reflectance, Rgb(0.0f));
  EXPECT_EQ(chrome.specular_reflectance, Rgb(1.0f));
  EXPECT_EQ(chrome.microfacet_roughness, 0.0f);  // a mirror (below the GGX delta threshold)
  const Material& glass = s.materials[2];
  EXPECT_EQ(glass.microfacet, Material::Microfacet::kDielectric);
  EXPECT_EQ(glass.specular_transmittance, Rgb(1.0f));
  EXPECT_EQ(glass.diffuse_reflectance, Rgb(0.0f));
  EXPECT_FLOAT_EQ(glass.ior, 1.33f);
  EXPECT_FALSE(glass.one_sided);
  EXPECT_EQ(s.materials[3].emission, Rgb(8.0f, 4.0f, 2.0f));
  EXPECT_EQ(s.num_lights, 1u);
  // One warning for Wood's unapplied normal texture (its image is never decoded: not an error).
  // baseColorTexture is applied (tests/common/texture_test.cpp).
  int texture_warnings = 0;
  for (const std::string& w : s.warnings)
    if (w.find("textures not applied") != std::string::npos) {
      ++texture_warnings;
      EXPECT_THAT(w, HasSubstr("scene.gltf: materials[0] 'Wood': textures not applied: normalTexture"));
    }
  EXPECT_EQ(texture_warnings, 1);
}

// An image in a buffer view that leaves its buffer: an error naming the element, never a read
// past the buffer (tinygltf hands the view's bytes over unchecked; gltf_textures.cpp checks).
TEST(GltfLoader, ImageBufferViewOutsideItsBufferIsAnError) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string rest = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" + std::string(kTriangleMesh) +
                           R"(,"textures":[{"source":0}],"images":[{"bufferView":3,"mimeType":"image/png"}],
      "materials":[{"name":"lamp","emissiveFactor":[1,1,1],
                    "pbrMetallicRoughness":{"baseColorTexture":{"index":0}}}])";
  std::string json = Triangle().Json(rest);
  // View 3, after the three of the accessors: a million bytes past the buffer's end.
  const std::string views_end = "],\"accessors\":[";
  const size_t at = json.find(views_end);
  ASSERT_NE(at, std::string::npos);
  json.insert(at, R"(,{"buffer":0,"byteOffset":1000000,"byteLength":4096})");
  EXPECT_THAT(
      ErrorOf(dir.Write("scene.gltf", json)),
      HasSubstr("scene.gltf: materials[0].pbrMetallicRoughness.baseColorTexture: textures[0]: images[0]: "
                "buffer view outside its buffer"));
}

TEST(GltfLoader, NonTriangleModesAreSkippedWithAWarningNamingThePrimitive) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string rest = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0},"material":0},{"attributes":{"POSITION":0},"mode":1}]}],)";
  const SceneDescription s = LoadGltf(dir.Write("scene.gltf", Triangle().Json(rest + kLamp)));
  EXPECT_EQ(s.triangles.size(), 1u);
  EXPECT_THAT(::testing::PrintToString(s.warnings),
              HasSubstr("meshes[0].primitives[1]: mode 1 is not TRIANGLES"));
}

TEST(GltfLoader, ErrorsNameTheElement) {
  test_util::TempDir dir("pf_gltf_test");
  GltfBuilder b = Triangle();
  const int bad = b.AddIndices16({0, 1, 7});
  const std::string scene = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)";
  EXPECT_THAT(
      ErrorOf(dir.Write("a.gltf", b.Json(scene + R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},
      "indices":2},{"attributes":{"POSITION":0},"indices":)" +
                                         std::to_string(bad) + "}]}]"))),
      HasSubstr("a.gltf: meshes[0].primitives[1]: index 7 is out of range (3 vertices)"));
  EXPECT_THAT(ErrorOf(dir.Write(
                  "b.gltf", b.Json(scene + R"("meshes":[{"primitives":[{"attributes":{"NORMAL":1}}]}])"))),
              HasSubstr("b.gltf: meshes[0].primitives[0]: no POSITION attribute"));
  EXPECT_THAT(
      ErrorOf(dir.Write("c.gltf", b.Json(scene + R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},
      "material":5}]}])"))),
      HasSubstr("c.gltf: meshes[0].primitives[0]: material 5 does not exist"));
  // A node that is its own child.
  EXPECT_THAT(ErrorOf(dir.Write("d.gltf", b.Json(R"("scenes":[{"nodes":[0]}],"nodes":[{"children":[0]}])"))),
              HasSubstr("d.gltf: nodes[0]: appears twice in the node hierarchy"));
}

TEST(GltfLoader, NaNInABufferNamesThePrimitiveAndTheAccessor) {
  test_util::TempDir dir("pf_gltf_test");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  GltfBuilder b;
  b.AddVec3({0, 0, 0, 1, nan, 0, 0, 1, 0});
  EXPECT_THAT(ErrorOf(dir.Write("scene.gltf", b.Json(R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}])"))),
              HasSubstr("scene.gltf: meshes[0].primitives[0]: accessors[0]: element 1 is not finite"));
}

TEST(GltfLoader, MissingBinIsAnErrorNamingTheFile) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string error =
      ErrorOf(dir.Write("scene.gltf", Triangle().Json(R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" +
                                                          std::string(kTriangleMesh),
                                                      "missing.bin")));
  EXPECT_THAT(error, HasSubstr("scene.gltf: "));
  EXPECT_THAT(error, HasSubstr("missing.bin"));
  // tinygltf's second look, in the working directory, is not the scene's: no refusal to report.
  EXPECT_THAT(error, ::testing::Not(HasSubstr("outside the scene folder")));
}

TEST(GltfLoader, ExternalBinLoadsAndABinOutsideTheFolderIsRefused) {
  test_util::TempDir dir("pf_gltf_test");
  const GltfBuilder b = Triangle();
  dir.Write("scene/mesh.bin", b.Bin());
  dir.Write("outside.bin", b.Bin());
  const std::string rest =
      R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" + std::string(kTriangleMesh) + "," + kLamp;
  EXPECT_EQ(LoadGltf(dir.Write("scene/a.gltf", b.Json(rest, "mesh.bin"))).triangles.size(), 1u);
  const std::string error = ErrorOf(dir.Write("scene/b.gltf", b.Json(rest, "../outside.bin")));
  EXPECT_THAT(error, HasSubstr("b.gltf: '../outside.bin' resolves outside the scene folder"));
}

TEST(GltfLoader, DracoIsRefused) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string rest = R"("extensionsUsed":["KHR_draco_mesh_compression"],
      "extensionsRequired":["KHR_draco_mesh_compression"],"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" +
                           std::string(kTriangleMesh) + "," + kLamp;
  EXPECT_THAT(ErrorOf(dir.Write("scene.gltf", Triangle().Json(rest))),
              HasSubstr("scene.gltf: extensionsRequired: 'KHR_draco_mesh_compression' is not supported"));
}

TEST(GltfLoader, LoadSceneDispatchesAndRequiresALight) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string scene = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" + std::string(kTriangleMesh);
  EXPECT_EQ(LoadScene(dir.Write("lit.GLTF", Triangle().Json(scene + "," + kLamp))).num_lights, 1u);
  try {
    LoadScene(dir.Write("dark.gltf", Triangle().Json(scene + R"(,"materials":[{"name":"grey"}])")));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("the scene has no light"));
    EXPECT_THAT(e.what(), HasSubstr("KHR_lights_punctual"));
  }
  // A manifest may name a glTF as its geometry; its lights add to the file's.
  dir.Write("m.json",
            R"({"geometry":"lit.GLTF","lights":[{"type":"point","position":[0,1,0],"intensity":1}]})");
  const SceneDescription m = LoadScene(dir.path() / "m.json");
  EXPECT_EQ(m.num_lights, 2u);
  EXPECT_EQ(m.punctual_lights.at(0).light, 1u);
}

TEST(GltfLoader, BundleShipsBuffersAndReferencedImagesOnly) {
  test_util::TempDir dir("pf_gltf_test");
  const GltfBuilder b = Triangle();
  dir.Write("scene/mesh.bin", b.Bin());
  dir.Write("scene/tex/wood%.png", "not decoded");
  dir.Write("scene/preview.png", "an output");
  const std::string rest = R"("scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)" + std::string(kTriangleMesh) +
                           "," + R"("images":[{"uri":"tex/wood%25.png"}],)" + kLamp;
  const auto entry = dir.Write("scene/scene.gltf", b.Json(rest, "mesh.bin"));
  const SceneBundle bundle = CollectBundle(entry);
  std::vector<std::string> paths;
  for (const auto& [path, content] : bundle.files) paths.push_back(path);
  EXPECT_THAT(paths, ::testing::ElementsAre("mesh.bin", "scene.gltf", "tex/wood%.png"));
  // The farm's side: written to a fresh folder and loaded from there.
  WriteBundle(bundle, dir.path() / "stored");
  EXPECT_EQ(LoadBundle(dir.path() / "stored", bundle.entry).triangles.size(), 1u);
}

}  // namespace
}  // namespace pf
