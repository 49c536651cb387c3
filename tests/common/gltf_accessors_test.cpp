// glTF accessor reading (common/scene/gltf_accessors.h).
#include "common/scene/gltf_accessors.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <limits>
#include <string>

#include "common/core/error.h"
#include "tests/common/gltf_test_util.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

using gltf_test::Base64;
using gltf_test::Floats;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

// One buffer holding `bytes`, one view over all of it, one accessor.
GltfDocument OneAccessor(const test_util::TempDir& dir, const std::string& bytes, int component_type,
                         const std::string& type, uint64_t count) {
  const std::string json =
      R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":)" + std::to_string(bytes.size()) +
      R"(,"uri":"data:application/octet-stream;base64,)" + Base64(bytes) +
      R"("}],"bufferViews":[{"buffer":0,"byteLength":)" + std::to_string(bytes.size()) +
      R"(}],"accessors":[{"bufferView":0,"componentType":)" + std::to_string(component_type) +
      R"(,"count":)" + std::to_string(count) + R"(,"type":")" + type + R"("}]})";
  return ReadGltfDocument(dir.Write("scene.gltf", json));
}

TEST(GltfAccessors, IndicesOfEveryWidth) {
  test_util::TempDir dir("pf_gltf_test");
  EXPECT_THAT(ReadGltfIndices(OneAccessor(dir, std::string("\x00\x02\xff", 3), 5121, "SCALAR", 3), 0),
              ElementsAre(0u, 2u, 255u));
  EXPECT_THAT(ReadGltfIndices(OneAccessor(dir, std::string("\x01\x00\x34\x12", 4), 5123, "SCALAR", 2), 0),
              ElementsAre(1u, 0x1234u));
  EXPECT_THAT(ReadGltfIndices(OneAccessor(dir, std::string("\x78\x56\x34\x12", 4), 5125, "SCALAR", 1), 0),
              ElementsAre(0x12345678u));
}

TEST(GltfAccessors, ReadsPositions) {
  test_util::TempDir dir("pf_gltf_test");
  const auto p = ReadGltfVec3(OneAccessor(dir, Floats({1, 2, 3, -4, 5.5f, 6}), 5126, "VEC3", 2), 0);
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[1].x, -4.0);
  EXPECT_EQ(p[1].y, 5.5);
}

TEST(GltfAccessors, NaNNamesTheAccessorAndElement) {
  test_util::TempDir dir("pf_gltf_test");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const GltfDocument doc = OneAccessor(dir, Floats({0, 0, 0, 1, nan, 1}), 5126, "VEC3", 2);
  try {
    ReadGltfVec3(doc, 0);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scene.gltf: accessors[0]: element 1 is not finite"));
  }
}

TEST(GltfAccessors, OutOfRangeAccessorIsAnError) {
  test_util::TempDir dir("pf_gltf_test");
  // count 3 VEC3 floats = 36 bytes, but the view holds 24.
  const GltfDocument doc = OneAccessor(dir, Floats({0, 0, 0, 1, 1, 1}), 5126, "VEC3", 3);
  try {
    ReadGltfVec3(doc, 0);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scene.gltf: accessors[0]: out of range"));
  }
}

// A count whose byte extent wraps a 64-bit product (16 · 2^62 = 2^66 ≡ 0) must not pass the range
// check: it would read and write far past the buffer.
TEST(GltfAccessors, AHugeCountCannotWrapTheRangeCheck) {
  test_util::TempDir dir("pf_gltf_test");
  const GltfDocument doc = OneAccessor(dir, Floats({0, 0, 0, 1}), 5126, "VEC4", (uint64_t(1) << 62) + 1);
  try {
    ReadGltfFloats(doc, 0, 4);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scene.gltf: accessors[0]: out of range"));
  }
}

}  // namespace
}  // namespace pf
