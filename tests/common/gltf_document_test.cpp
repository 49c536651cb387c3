// glTF 2.0 parsing and the extension policy (common/scene/gltf_document.h).
#include "common/scene/gltf_document.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <tiny_gltf.h>

#include <cstdint>
#include <fstream>
#include <string>

#include "common/core/error.h"
#include "tests/common/gltf_test_util.h"
#include "tests/util/input_error.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using ::testing::HasSubstr;

// One triangle; its 36-byte position buffer is all zeros ("AAAA" is three zero bytes in base64).
std::string TriangleGltf(const std::string& extra = "", const std::string& buffer_uri = "") {
  const std::string uri =
      buffer_uri.empty() ? "data:application/octet-stream;base64," + std::string(48, 'A') : buffer_uri;
  return R"({"asset":{"version":"2.0"},)" + extra + R"("scenes":[{"nodes":[0]}],"scene":0,
    "nodes":[{"mesh":0}],
    "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
    "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
                  "min":[0,0,0],"max":[0,0,0]}],
    "bufferViews":[{"buffer":0,"byteLength":36}],
    "buffers":[{"byteLength":36,"uri":")" +
         uri + R"("}]})";
}

std::string ErrorOf(const std::filesystem::path& p) {
  return testing::InputErrorOf([&] { ReadGltfDocument(p); });
}

TEST(GltfDocument, ReadsAValidFileWithoutWarnings) {
  test_util::TempDir dir("pf_gltf_test");
  const GltfDocument doc = ReadGltfDocument(dir.Write("scene.gltf", TriangleGltf()));
  ASSERT_EQ(doc.model->meshes.size(), 1u);
  EXPECT_EQ(doc.model->accessors[0].count, 3u);
  EXPECT_EQ(doc.model->buffers[0].data.size(), 36u);
  EXPECT_TRUE(doc.warnings.empty());
}

TEST(GltfDocument, MissingFileNamesIt) {
  test_util::TempDir dir("pf_gltf_test");
  EXPECT_THAT(ErrorOf(dir.path() / "nothere.gltf"), HasSubstr("nothere.gltf: no such file"));
}

TEST(GltfDocument, MalformedJsonIsAnInputErrorNamingTheFile) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string msg = ErrorOf(dir.Write("scene.gltf", R"({"asset":{"version":"2.0"},)"));
  EXPECT_THAT(msg, HasSubstr("scene.gltf: "));
}

TEST(GltfDocument, MissingBufferFileIsAnInputError) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string msg = ErrorOf(dir.Write("scene.gltf", TriangleGltf("", "missing.bin")));
  EXPECT_THAT(msg, HasSubstr("scene.gltf: "));
  EXPECT_THAT(msg, HasSubstr("missing.bin"));
}

TEST(GltfDocument, RequiredDracoIsRefusedByName) {
  test_util::TempDir dir("pf_gltf_test");
  const std::string msg =
      ErrorOf(dir.Write("scene.gltf", TriangleGltf(R"("extensionsUsed":["KHR_draco_mesh_compression"],
                                    "extensionsRequired":["KHR_draco_mesh_compression"],)")));
  EXPECT_THAT(msg,
              HasSubstr("scene.gltf: extensionsRequired: 'KHR_draco_mesh_compression' is not supported"));
}

TEST(GltfDocument, UsedOnlyExtensionsWarnOnceEachAndSupportedOnesDoNot) {
  test_util::TempDir dir("pf_gltf_test");
  const GltfDocument doc = ReadGltfDocument(dir.Write(
      "scene.gltf",
      TriangleGltf(
          R"("extensionsUsed":["KHR_texture_transform","KHR_lights_punctual","KHR_materials_volume"],)")));
  ASSERT_EQ(doc.warnings.size(), 2u);
  EXPECT_EQ(doc.warnings[0], "scene.gltf: extensionsUsed: 'KHR_texture_transform' is not supported; ignored");
  EXPECT_THAT(doc.warnings[1], HasSubstr("'KHR_materials_volume'"));
}

TEST(GltfDocument, FileReferencesAreDecodedAndSkipDataUris) {
  EXPECT_THAT(
      GltfFileReferences(
          R"({"buffers":[{"uri":"mesh%20a+b.bin"},{"uri":"data:application/octet-stream;base64,AAAA"}],
                                    "images":[{"uri":"tex/wood.png"},{"bufferView":0}]})"),
      ::testing::ElementsAre("mesh a b.bin", "tex/wood.png"));
  EXPECT_TRUE(GltfFileReferences("not json").empty());
}

// A GLB (glTF 2.0 spec, "Binary glTF Layout"): 12-byte header, JSON chunk, BIN chunk, each chunk
// padded to four bytes.
TEST(GltfDocument, ReadsABinaryContainer) {
  test_util::TempDir dir("pf_gltf_test");
  std::string json = R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":36}],
    "bufferViews":[{"buffer":0,"byteLength":36}],
    "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}]})";
  while (json.size() % 4 != 0) json += ' ';
  const std::string bin(36, '\x01');
  std::string bytes;
  auto u32 = [&bytes](uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes += static_cast<char>((v >> (8 * i)) & 0xFF);
  };
  u32(0x46546C67);  // "glTF"
  u32(2);
  u32(static_cast<uint32_t>(12 + 8 + json.size() + 8 + bin.size()));
  u32(static_cast<uint32_t>(json.size()));
  u32(0x4E4F534A);  // "JSON"
  bytes += json;
  u32(static_cast<uint32_t>(bin.size()));
  u32(0x004E4942);  // "BIN\0"
  bytes += bin;
  const auto path = dir.path() / "scene.glb";
  std::ofstream(path, std::ios::binary) << bytes;
  const GltfDocument doc = ReadGltfDocument(path);
  ASSERT_EQ(doc.model->buffers.size(), 1u);
  ASSERT_EQ(doc.model->buffers[0].data.size(), 36u);
  EXPECT_EQ(doc.model->buffers[0].data[35], 1);
}

}  // namespace
}  // namespace pf
