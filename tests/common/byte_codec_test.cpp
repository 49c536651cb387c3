// common/core/byte_codec.h: the project's one little-endian codec, byte for byte, and the
// accumulator checkpoint written with it.

#include "common/core/byte_codec.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <vector>

#include "common/plan/accumulator.h"

namespace pf {
namespace {
using ::testing::HasSubstr;

std::string Bytes(std::initializer_list<int> b) {
  std::string s;
  for (int v : b) s.push_back(char(v));
  return s;
}

TEST(ByteCodec, WritesLeastSignificantByteFirst) {
  std::string out;
  ByteWriter w(out);
  w.Put<uint32_t>(0x01020304u);
  w.Put<int16_t>(-2);
  w.Put<float>(1.0f);   // IEEE-754 0x3f800000
  w.Put<double>(-2.0);  // 0xc000000000000000
  w.Put<uint8_t>(0xab);
  EXPECT_EQ(out, Bytes({4, 3, 2, 1, 0xfe, 0xff, 0, 0, 0x80, 0x3f, 0, 0, 0, 0, 0, 0, 0, 0xc0, 0xab}));
}

TEST(ByteCodec, ReadsBackEveryTypeAndArrays) {
  std::string out;
  ByteWriter w(out);
  const std::vector<int64_t> a = {-1, 0, std::numeric_limits<int64_t>::min(), 1ll << 40};
  const std::vector<float> f = {0.5f, -0.0f, std::numeric_limits<float>::infinity(), 3.25e-20f};
  w.Put<uint64_t>(0xfedcba9876543210ull);
  w.PutArray<int64_t>(a);
  w.PutArray<float>(f);
  w.PutBytes("tail");
  ByteReader r(out, "test");
  EXPECT_EQ(r.Get<uint64_t>(), 0xfedcba9876543210ull);
  std::vector<int64_t> a2(a.size());
  std::vector<float> f2(f.size());
  r.GetArray<int64_t>(a2);
  r.GetArray<float>(f2);
  EXPECT_EQ(a2, a);
  EXPECT_EQ(f2, f);
  EXPECT_TRUE(std::signbit(f2[1]));
  EXPECT_EQ(r.GetBytes(4), "tail");
  EXPECT_TRUE(r.empty());
}

TEST(ByteCodec, ShortInputIsAnInputErrorNamingTheFormat) {
  const std::string three = Bytes({1, 2, 3});
  ByteReader r(three, "journal entry");
  try {
    r.Get<uint32_t>();
    ADD_FAILURE() << "read past the end";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("journal entry: truncated"));
  }
  EXPECT_EQ(r.remaining(), 3u) << "a failed read consumes nothing";
  std::vector<float> two(2);
  EXPECT_THROW(r.GetArray<float>(two), InputError);
  EXPECT_THROW(r.GetBytes(4), InputError);
}

TEST(ByteCodec, AccumulatorCheckpointIsLittleEndianWithItsDocumentedLayout) {
  Accumulator acc(3, 2);
  const std::string bytes = acc.Serialize();
  ASSERT_GE(bytes.size(), 16u);
  EXPECT_EQ(bytes.substr(0, 8), "PFACCUM1");
  EXPECT_EQ(bytes.substr(8, 8), Bytes({3, 0, 0, 0, 2, 0, 0, 0}));
  EXPECT_EQ(bytes.size(), 8 + 8 + 16 + 6 * 48u);
  EXPECT_EQ(Accumulator::Deserialize(bytes), acc);
  EXPECT_THROW(Accumulator::Deserialize(bytes.substr(0, bytes.size() - 1)), InputError);
  EXPECT_THROW(Accumulator::Deserialize(bytes + "x"), InputError);
  // A header that claims a huge image is refused before anything is allocated for it.
  std::string huge = bytes;
  huge.replace(8, 8, Bytes({0, 0x40, 0, 0, 0, 0x40, 0, 0}));
  EXPECT_THROW(Accumulator::Deserialize(huge), InputError);
}

}  // namespace
}  // namespace pf
