// Tests of common/image/: EXR and PNG I/O, image comparison.

#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/core/error.h"
#include "common/image/exr_io.h"
#include "common/image/image.h"
#include "common/image/image_diff.h"
#include "common/image/png_io.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test_util::TempDirTest;
std::string ReadBytes(const fs::path& path) {
  return test_util::ReadFileBytes(path);
}

void WriteBytes(const fs::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
}

// Values that a lossy or converting path would not keep: signed zeros, subnormals, the
// extremes of float, infinities, NaN, and values with all mantissa bits in use.
Image ExtremeValuesImage() {
  const float values[] = {0.0f,
                          -0.0f,
                          std::numeric_limits<float>::denorm_min(),
                          1e-42f,
                          std::numeric_limits<float>::min(),
                          1e-30f,
                          1.0f / 3.0f,
                          -2.718281828f,
                          kPi,
                          65504.0f,
                          65505.0f,  // just above the largest half
                          1e30f,
                          3e38f,
                          std::numeric_limits<float>::max(),
                          -std::numeric_limits<float>::max(),
                          std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::quiet_NaN(),
                          0.1f,
                          1.0f};
  constexpr int kCount = std::size(values);
  Image image(7, 5);
  for (size_t i = 0; i < image.size(); ++i) {
    // Channels cycle through the list at different rates so every channel sees every value.
    image[i] = Rgb(values[i % kCount], values[(3 * i + 1) % kCount], values[(7 * i + 2) % kCount]);
  }
  return image;
}

void ExpectBitIdentical(const Image& expected, const Image& actual) {
  ASSERT_EQ(expected.width(), actual.width());
  ASSERT_EQ(expected.height(), actual.height());
  for (size_t i = 0; i < expected.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(std::bit_cast<uint32_t>(expected[i][c]), std::bit_cast<uint32_t>(actual[i][c]))
          << "pixel " << i << " channel " << c << ": " << expected[i][c] << " vs " << actual[i][c];
    }
  }
}

// ---------------------------------------------------------------------------------------------
// EXR

class ExrCompressionTest : public TempDirTest, public ::testing::WithParamInterface<ExrCompression> {};

TEST_P(ExrCompressionTest, FileRoundTripIsBitExact) {
  const Image image = ExtremeValuesImage();
  const fs::path path = dir_ / "extreme.exr";
  WriteExr(path, image, {}, GetParam());
  ExpectBitIdentical(image, ReadExr(path));
}

TEST_P(ExrCompressionTest, MemoryRoundTripIsBitExactAndMatchesFile) {
  const Image image = ExtremeValuesImage();
  const ImageMetadata metadata = {{"spp", "64"}};
  const std::string bytes = EncodeExrToMemory(image, metadata, GetParam());
  ImageMetadata read_metadata;
  ExpectBitIdentical(image, DecodeExrFromMemory(bytes, &read_metadata));
  EXPECT_EQ(read_metadata, metadata);
  // Deterministic encoding, and the file holds exactly the in-memory encoding.
  EXPECT_EQ(EncodeExrToMemory(image, metadata, GetParam()), bytes);
  const fs::path path = dir_ / "same.exr";
  WriteExr(path, image, metadata, GetParam());
  EXPECT_EQ(ReadBytes(path), bytes);
}

INSTANTIATE_TEST_SUITE_P(AllCompressions, ExrCompressionTest,
                         ::testing::Values(ExrCompression::kNone, ExrCompression::kZip, ExrCompression::kPiz),
                         [](const auto& info) {
                           switch (info.param) {
                             case ExrCompression::kNone:
                               return std::string("None");
                             case ExrCompression::kZip:
                               return std::string("Zip");
                             case ExrCompression::kPiz:
                               return std::string("Piz");
                           }
                           return std::string("Unknown");
                         });

class ExrIoTest : public TempDirTest {};

TEST_F(ExrIoTest, CompressionsDifferInSize) {
  // A smooth image compresses, so kNone must be the largest encoding.
  Image image(64, 64);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) image.at(x, y) = Rgb(x / 64.0f, y / 64.0f, 0.5f);
  }
  const size_t none = EncodeExrToMemory(image, {}, ExrCompression::kNone).size();
  EXPECT_GE(none, size_t(64 * 64 * 12));
  EXPECT_LT(EncodeExrToMemory(image, {}, ExrCompression::kZip).size(), none);
  EXPECT_LT(EncodeExrToMemory(image, {}, ExrCompression::kPiz).size(), none);
}

TEST_F(ExrIoTest, MetadataRoundTrip) {
  const ImageMetadata metadata = {
      {"spp", "1024"},
      {"seed", "42"},
      {"empty", ""},
      {"scene", "scenes/cornell box/manifest.json"},
      {"a_key_much_longer_than_thirty_one_characters", "long names need the long-name flag"},
      {"utf8", "caf\xc3\xa9 \xe2\x86\x92 \xf0\x9f\x93\xb7"},
      {"multiline", "line 1\nline 2\ttab"},
  };
  const fs::path path = dir_ / "meta.exr";
  WriteExr(path, Image(3, 2), metadata);
  ImageMetadata read;
  read["stale"] = "must be replaced";
  const Image image = ReadExr(path, &read);
  EXPECT_EQ(image.width(), 3);
  EXPECT_EQ(image.height(), 2);
  EXPECT_EQ(read, metadata);
}

TEST_F(ExrIoTest, AtomicWriteLeavesNoTemporaryFile) {
  const fs::path path = dir_ / "progressive.exr";
  Image first(4, 4), second(4, 4);
  for (size_t i = 0; i < second.size(); ++i) second[i] = Rgb(float(i));
  WriteExr(path, first);
  WriteExr(path, second);  // replaces the existing file
  EXPECT_EQ(DirListing(), std::vector<std::string>{"progressive.exr"});
  ExpectBitIdentical(second, ReadExr(path));
}

TEST_F(ExrIoTest, WriteIntoMissingDirectoryIsSystemErrorWithPath) {
  const fs::path path = dir_ / "no_such_dir" / "out.exr";
  EXPECT_THAT([&] { (void)WriteExr(path, Image(2, 2)); },
              ::testing::ThrowsMessage<SystemError>(HasSubstr(path.string())))
      << "expected SystemError";
  EXPECT_TRUE(DirListing().empty());
}

TEST_F(ExrIoTest, EmptyImageIsInputError) {
  EXPECT_THROW(WriteExr(dir_ / "empty.exr", Image()), InputError);
  EXPECT_THROW(EncodeExrToMemory(Image(0, 5)), InputError);
  EXPECT_TRUE(DirListing().empty());
}

TEST_F(ExrIoTest, MissingFileIsSystemErrorWithPath) {
  const fs::path path = dir_ / "missing.exr";
  EXPECT_THAT([&] { (void)ReadExr(path); }, ::testing::ThrowsMessage<SystemError>(HasSubstr(path.string())))
      << "expected SystemError";
}

TEST_F(ExrIoTest, NonExrFileIsSystemErrorWithPath) {
  const fs::path path = dir_ / "not_an_image.exr";
  WriteBytes(path, "this is a text file, not an OpenEXR image\n");
  EXPECT_THAT([&] { (void)ReadExr(path); }, ::testing::ThrowsMessage<SystemError>(HasSubstr(path.string())))
      << "expected SystemError";
  EXPECT_THROW(DecodeExrFromMemory("\x76\x2f\x31\x01 and then garbage"), SystemError);
  EXPECT_THROW(DecodeExrFromMemory(""), SystemError);
}

TEST_F(ExrIoTest, TruncatedFileIsSystemErrorWithPath) {
  Image image(16, 16);
  for (size_t i = 0; i < image.size(); ++i) image[i] = Rgb(float(i), 0.5f, -float(i));
  const std::string bytes = EncodeExrToMemory(image, {{"k", "v"}}, ExrCompression::kNone);
  const fs::path path = dir_ / "truncated.exr";
  WriteBytes(path, std::string_view(bytes).substr(0, bytes.size() / 2));
  EXPECT_THAT([&] { (void)ReadExr(path); }, ::testing::ThrowsMessage<SystemError>(HasSubstr(path.string())))
      << "expected SystemError";
  // Every cut, from inside the magic number to the last byte, is an error and not a crash.
  for (size_t length : {size_t(0), size_t(3), size_t(8), size_t(40), size_t(200), bytes.size() / 3,
                        bytes.size() - 20, bytes.size() - 1}) {
    EXPECT_THROW(DecodeExrFromMemory(std::string_view(bytes).substr(0, length)), SystemError)
        << "length " << length << " of " << bytes.size();
  }
}

// Builds a small uncompressed scanline EXR by hand (OpenEXR file layout, version 2), so that
// the tests can exercise what WriteExr never produces: HALF channels, data windows that differ
// from the display window, missing channels.
class HandMadeExr {
 public:
  struct Box {
    int32_t min_x, min_y, max_x, max_y;
  };

  // `channels` must be sorted by name, as the file format requires. Channel values are HALF.
  static std::string Build(const std::vector<std::string>& channels, Box data, Box display,
                           uint16_t (*value)(const std::string& channel, int x, int y)) {
    HandMadeExr exr;
    exr.Bytes("\x76\x2f\x31\x01", 4);
    exr.Int32(2);  // version 2, single-part scanline, short names

    std::string chlist;
    for (const std::string& name : channels) {
      chlist += name;
      chlist += '\0';
      AppendInt32(chlist, 1);          // HALF
      chlist += std::string(4, '\0');  // pLinear + reserved
      AppendInt32(chlist, 1);          // xSampling
      AppendInt32(chlist, 1);          // ySampling
    }
    chlist += '\0';
    exr.Attribute("channels", "chlist", chlist);
    exr.Attribute("compression", "compression", std::string(1, '\0'));
    exr.Attribute("dataWindow", "box2i", BoxBytes(data));
    exr.Attribute("displayWindow", "box2i", BoxBytes(display));
    exr.Attribute("lineOrder", "lineOrder", std::string(1, '\0'));
    exr.Attribute("pixelAspectRatio", "float", FloatBytes(1.0f));
    exr.Attribute("screenWindowCenter", "v2f", FloatBytes(0.0f) + FloatBytes(0.0f));
    exr.Attribute("screenWindowWidth", "float", FloatBytes(1.0f));
    exr.out_ += '\0';

    const int width = data.max_x - data.min_x + 1;
    const int height = data.max_y - data.min_y + 1;
    const size_t line_bytes = channels.size() * size_t(width) * 2;
    const size_t first_line = exr.out_.size() + 8 * size_t(height);
    for (int i = 0; i < height; ++i) exr.Int64(first_line + size_t(i) * (8 + line_bytes));
    for (int y = data.min_y; y <= data.max_y; ++y) {
      exr.Int32(y);
      exr.Int32(int32_t(line_bytes));
      for (const std::string& name : channels) {
        for (int x = data.min_x; x <= data.max_x; ++x) {
          const uint16_t h = value(name, x, y);
          exr.Bytes(reinterpret_cast<const char*>(&h), 2);  // little-endian host
        }
      }
    }
    return exr.out_;
  }

 private:
  static void AppendInt32(std::string& s, int32_t v) { s.append(reinterpret_cast<const char*>(&v), 4); }
  static std::string FloatBytes(float f) { return std::string(reinterpret_cast<char*>(&f), 4); }
  static std::string BoxBytes(Box b) {
    std::string s;
    for (int32_t v : {b.min_x, b.min_y, b.max_x, b.max_y}) AppendInt32(s, v);
    return s;
  }
  void Bytes(const char* p, size_t n) { out_.append(p, n); }
  void Int32(int32_t v) { AppendInt32(out_, v); }
  void Int64(uint64_t v) { out_.append(reinterpret_cast<const char*>(&v), 8); }
  void Attribute(const char* name, const char* type, const std::string& value) {
    out_ += name;
    out_ += '\0';
    out_ += type;
    out_ += '\0';
    Int32(int32_t(value.size()));
    out_ += value;
  }

  std::string out_;
};

static_assert(std::endian::native == std::endian::little, "HandMadeExr writes host order");

// HALF encodings of a few exact values.
constexpr uint16_t kHalfOne = 0x3C00, kHalfTwo = 0x4000, kHalfHalf = 0x3800;

// The same colour (1, 2, 0.5) everywhere.
uint16_t CodedHalf(const std::string& channel, int /*x*/, int /*y*/) {
  return channel == "R" ? kHalfOne : (channel == "G" ? kHalfTwo : kHalfHalf);
}

TEST_F(ExrIoTest, ReadsHalfChannels) {
  const std::string bytes = HandMadeExr::Build({"B", "G", "R"}, {0, 0, 2, 1}, {0, 0, 2, 1}, CodedHalf);
  ImageMetadata metadata = {{"stale", "x"}};
  const Image image = DecodeExrFromMemory(bytes, &metadata);
  ASSERT_EQ(image.width(), 3);
  ASSERT_EQ(image.height(), 2);
  for (size_t i = 0; i < image.size(); ++i) EXPECT_EQ(image[i], Rgb(1.0f, 2.0f, 0.5f));
  EXPECT_TRUE(metadata.empty());
}

TEST_F(ExrIoTest, DataWindowInsideDisplayWindowIsPlacedAndPadded) {
  // Display 4x3 at the origin; data only at x in [1,2], y in [1,2].
  const std::string bytes = HandMadeExr::Build({"B", "G", "R"}, {1, 1, 2, 2}, {0, 0, 3, 2}, CodedHalf);
  const fs::path path = dir_ / "crop.exr";
  WriteBytes(path, bytes);
  const Image image = ReadExr(path);
  ASSERT_EQ(image.width(), 4);
  ASSERT_EQ(image.height(), 3);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 4; ++x) {
      const bool has_data = x >= 1 && x <= 2 && y >= 1;
      EXPECT_EQ(image.at(x, y), has_data ? Rgb(1.0f, 2.0f, 0.5f) : Rgb(0.0f)) << "at " << x << "," << y;
    }
  }
}

uint16_t PositionHalf(const std::string& channel, int x, int y) {
  // R marks the column (x = -1, 0, 1 -> 0.5, 1, 2), G the row (y = 1, 2 -> 1, 2), B = 0.5.
  if (channel == "R") return x < 0 ? kHalfHalf : (x == 0 ? kHalfOne : kHalfTwo);
  if (channel == "G") return y == 1 ? kHalfOne : kHalfTwo;
  return kHalfHalf;
}

TEST_F(ExrIoTest, DataWindowOverlappingDisplayWindowIsCropped) {
  // Display (1,0)-(3,1) is 3x2; data (-1,1)-(1,2) overlaps it only at (1,1) -> image (0,1).
  const std::string bytes = HandMadeExr::Build({"B", "G", "R"}, {-1, 1, 1, 2}, {1, 0, 3, 1}, PositionHalf);
  const Image image = DecodeExrFromMemory(bytes);
  ASSERT_EQ(image.width(), 3);
  ASSERT_EQ(image.height(), 2);
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 3; ++x) {
      const Rgb expected = (x == 0 && y == 1) ? Rgb(2.0f, 1.0f, 0.5f) : Rgb(0.0f);
      EXPECT_EQ(image.at(x, y), expected) << "at " << x << "," << y;
    }
  }
}

TEST_F(ExrIoTest, MissingChannelIsSystemErrorNamingIt) {
  const std::string bytes = HandMadeExr::Build({"G", "R"}, {0, 0, 1, 1}, {0, 0, 1, 1}, CodedHalf);
  const fs::path path = dir_ / "no_blue.exr";
  WriteBytes(path, bytes);
  EXPECT_THAT([&] { (void)ReadExr(path); },
              ::testing::ThrowsMessage<SystemError>(
                  ::testing::AllOf(HasSubstr(path.string()), HasSubstr("missing channel \"B\""))))
      << "expected SystemError";
}

// ---------------------------------------------------------------------------------------------
// PNG

// The sRGB OETF written out independently of png_io.cpp.
int ExpectedSrgbByte(double linear) {
  const double v = std::clamp(linear, 0.0, 1.0);
  const double encoded = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
  return int(std::lround(encoded * 255));
}

uint32_t BigEndian32(const std::string& s, size_t offset) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v = (v << 8) | uint8_t(s[offset + i]);
  return v;
}

class PngIoTest : public TempDirTest {};

TEST_F(PngIoTest, WritesValidPngWithHeaderAndSrgbChunk) {
  const fs::path path = dir_ / "preview.png";
  WritePngPreview(path, Image(37, 11));
  EXPECT_EQ(DirListing(), std::vector<std::string>{"preview.png"});
  const std::string bytes = ReadBytes(path);
  ASSERT_GE(bytes.size(), size_t(33));
  EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  EXPECT_EQ(BigEndian32(bytes, 8), 13u);  // IHDR length
  EXPECT_EQ(bytes.substr(12, 4), "IHDR");
  EXPECT_EQ(BigEndian32(bytes, 16), 37u);
  EXPECT_EQ(BigEndian32(bytes, 20), 11u);
  EXPECT_EQ(uint8_t(bytes[24]), 8);  // bit depth
  EXPECT_EQ(uint8_t(bytes[25]), 2);  // colour type: RGB
  EXPECT_NE(bytes.find("sRGB"), std::string::npos);
  EXPECT_EQ(EncodePngPreview(Image(37, 11)), bytes);
}

TEST_F(PngIoTest, GradientMatchesSrgbFormula) {
  // Row 0: grey ramp 0..1 in 256 steps; row 1: the same ramp, with exposure +1 stop below.
  Image image(256, 2);
  for (int x = 0; x < 256; ++x) {
    image.at(x, 0) = Rgb(x / 255.0f);
    image.at(x, 1) = Rgb(x / 255.0f, 0.5f * x / 255.0f, 0.25f * x / 255.0f);
  }
  for (double stops : {0.0, 1.0, -2.0}) {
    const fs::path path = dir_ / ("ramp" + std::to_string(int(stops)) + ".png");
    WritePngPreview(path, image, {.exposure_stops = stops});
    const Png8Image png = ReadPng8(path);
    ASSERT_EQ(png.width, 256);
    ASSERT_EQ(png.height, 2);
    ASSERT_EQ(png.rgb.size(), size_t(256 * 2 * 3));
    const double scale = std::exp2(stops);
    for (int y = 0; y < 2; ++y) {
      for (int x = 0; x < 256; ++x) {
        for (int c = 0; c < 3; ++c) {
          EXPECT_EQ(png.rgb[(size_t(y) * 256 + x) * 3 + c],
                    ExpectedSrgbByte(double(image.at(x, y)[c]) * scale))
              << "stops " << stops << " at " << x << "," << y << " channel " << c;
        }
      }
    }
  }
}

TEST_F(PngIoTest, KnownValuesAndNonFinite) {
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Image image(4, 1);
  image.at(0, 0) = Rgb(0.0f, 1.0f, 2.0f);
  image.at(1, 0) = Rgb(0.5f, 0.18f, -1.0f);
  image.at(2, 0) = Rgb(nan, inf, -inf);
  image.at(3, 0) = Rgb(0.001f, 0.0031308f, 0.04f);
  const std::vector<uint8_t> bytes = ToneMapToSrgb8(image);
  const std::vector<uint8_t> expected = {0,
                                         255,
                                         255,
                                         188,
                                         118,
                                         0,
                                         0,
                                         255,
                                         0,
                                         uint8_t(ExpectedSrgbByte(0.001)),
                                         uint8_t(ExpectedSrgbByte(0.0031308)),
                                         uint8_t(ExpectedSrgbByte(0.04))};
  EXPECT_EQ(bytes, expected);
}

TEST_F(PngIoTest, AutoExposureUsesThe99thPercentileLuminance) {
  // 199 grey pixels at 0.1 and one firefly: the firefly must not set the exposure.
  Image image(200, 1);
  for (size_t i = 0; i < image.size(); ++i) image[i] = Rgb(0.1f);
  image[57] = Rgb(1000.0f);
  EXPECT_NEAR(AutoExposureScale(image), 9.0, 1e-5);
  EXPECT_NEAR(PreviewScale(image, {.exposure_stops = 1, .auto_exposure = true}), 18.0, 1e-4);
  EXPECT_DOUBLE_EQ(PreviewScale(image, {.exposure_stops = 1}), 2.0);
  // The grey pixels come out at 0.9 (linear) -> sRGB byte of 0.9.
  const std::vector<uint8_t> bytes = ToneMapToSrgb8(image, {.auto_exposure = true});
  EXPECT_EQ(bytes[0], ExpectedSrgbByte(0.9));

  // Mostly black: the percentile is 0, so the brightest pixel is used instead.
  Image dark(100, 1);
  dark[3] = Rgb(2.0f);
  EXPECT_NEAR(AutoExposureScale(dark), 0.45, 1e-6);
  // All black or all non-finite: no scaling.
  EXPECT_EQ(AutoExposureScale(Image(10, 10)), 1.0);
  Image broken(2, 1);
  broken[0] = broken[1] = Rgb(std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(AutoExposureScale(broken), 1.0);
}

TEST_F(PngIoTest, ErrorsAreReportedWithPath) {
  EXPECT_THROW(WritePngPreview(dir_ / "empty.png", Image()), InputError);
  const fs::path unwritable = dir_ / "no_such_dir" / "p.png";
  EXPECT_THAT([&] { (void)WritePngPreview(unwritable, Image(2, 2)); },
              ::testing::ThrowsMessage<SystemError>(HasSubstr(unwritable.string())))
      << "expected SystemError";
  const fs::path not_png = dir_ / "text.png";
  WriteBytes(not_png, "not a png");
  EXPECT_THAT([&] { (void)ReadPng8(not_png); },
              ::testing::ThrowsMessage<SystemError>(HasSubstr(not_png.string())))
      << "expected SystemError";
  EXPECT_THROW(ReadPng8(dir_ / "missing.png"), SystemError);
  EXPECT_EQ(DirListing(), std::vector<std::string>{"text.png"});
}

// ---------------------------------------------------------------------------------------------
// Image comparison

// a and b of ImageDiffTest.HandComputedStats, row-major:
//   a = (1,1,1) (0,0,0)     b = (1,1,1) (0,0,1)
//       (2,0,0) (.5,.5,.5)      (1,0,0) (.5,.5,0)
// Differences: 0 0 0 | 0 0 -1 | 1 0 0 | 0 0 .5 over N = 12 channel values.
Image MakeImage2x2(Rgb p00, Rgb p10, Rgb p01, Rgb p11) {
  Image image(2, 2);
  image.at(0, 0) = p00;
  image.at(1, 0) = p10;
  image.at(0, 1) = p01;
  image.at(1, 1) = p11;
  return image;
}

TEST(ImageDiffTest, HandComputedStats) {
  const Image a = MakeImage2x2(Rgb(1), Rgb(0), Rgb(2, 0, 0), Rgb(0.5f));
  const Image b = MakeImage2x2(Rgb(1), Rgb(0, 0, 1), Rgb(1, 0, 0), Rgb(0.5f, 0.5f, 0));
  const ImageDiffStats s = CompareImages(a, b);
  EXPECT_EQ(s.pixels, 4u);
  EXPECT_EQ(s.nonfinite_a, 0u);
  EXPECT_EQ(s.nonfinite_b, 0u);
  // Squared errors 1 + 1 + 0.25 = 2.25 over 12.
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(2.25 / 12));
  // 1 / (1 + 0.01) twice, 0.25 / (0 + 0.01) once.
  EXPECT_DOUBLE_EQ(s.relative_mse, (2 / 1.01 + 25.0) / 12);
  EXPECT_DOUBLE_EQ(s.max_abs_error, 1.0);
  EXPECT_EQ(s.max_x, 1);  // first of the two errors of 1 in row-major order
  EXPECT_EQ(s.max_y, 0);
  EXPECT_DOUBLE_EQ(s.mean_a, 6.5 / 12);
  EXPECT_DOUBLE_EQ(s.mean_b, 6.0 / 12);
}

TEST(ImageDiffTest, IdenticalImagesHaveZeroError) {
  const Image a = MakeImage2x2(Rgb(1), Rgb(0.25f), Rgb(3, 2, 1), Rgb(0));
  const ImageDiffStats s = CompareImages(a, a);
  EXPECT_EQ(s.rmse, 0.0);
  EXPECT_EQ(s.relative_mse, 0.0);
  EXPECT_EQ(s.max_abs_error, 0.0);
  EXPECT_EQ(s.pixels, 4u);
  EXPECT_DOUBLE_EQ(s.mean_a, s.mean_b);
}

TEST(ImageDiffTest, SizeMismatchIsInputErrorNamingBothSizes) {
  EXPECT_THAT([&] { (void)CompareImages(Image(3, 2), Image(2, 2)); },
              ::testing::ThrowsMessage<InputError>(::testing::AllOf(HasSubstr("3x2"), HasSubstr("2x2"))))
      << "expected InputError";
  EXPECT_THROW(FalseColourError(Image(1, 4), Image(4, 1), 1.0), InputError);
}

TEST(ImageDiffTest, NonFinitePixelsAreCountedAndExcluded) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const Image a = MakeImage2x2(Rgb(1), Rgb(0, nan, 0), Rgb(2), Rgb(nan));
  const Image b = MakeImage2x2(Rgb(3), Rgb(0), Rgb(0, 0, -inf), Rgb(inf));
  const ImageDiffStats s = CompareImages(a, b);
  EXPECT_EQ(s.nonfinite_a, 2u);
  EXPECT_EQ(s.nonfinite_b, 2u);
  EXPECT_EQ(s.pixels, 1u);  // only (0,0) is finite in both
  EXPECT_DOUBLE_EQ(s.rmse, 2.0);
  EXPECT_DOUBLE_EQ(s.max_abs_error, 2.0);
  EXPECT_DOUBLE_EQ(s.mean_a, 1.0);
  EXPECT_DOUBLE_EQ(s.mean_b, 3.0);
  EXPECT_TRUE(std::isfinite(s.relative_mse));

  Image nan_pixel(1, 1);
  nan_pixel[0] = Rgb(nan);
  const ImageDiffStats none = CompareImages(Image(1, 1), nan_pixel);
  EXPECT_EQ(none.pixels, 0u);
  EXPECT_EQ(none.nonfinite_b, 1u);
  EXPECT_EQ(none.rmse, 0.0);
  EXPECT_EQ(none.max_x, -1);
  EXPECT_EQ(none.max_y, -1);
}

TEST(ImageDiffTest, ColormapRunsFromDarkPurpleToYellowWithRisingLuminance) {
  const Rgb bottom = ErrorColormap(0), top = ErrorColormap(1);
  EXPECT_GT(bottom.b, bottom.g);  // purple: blue and red over green
  EXPECT_GT(bottom.r, bottom.g);
  EXPECT_GT(top.r, top.b);  // yellow: red and green over blue
  EXPECT_GT(top.g, top.b);
  EXPECT_EQ(ErrorColormap(-3), bottom);
  EXPECT_EQ(ErrorColormap(7), top);
  float previous = -1;
  for (int i = 0; i <= 100; ++i) {
    const float luminance = ErrorColormap(i / 100.0).Luminance();
    EXPECT_GT(luminance, previous) << "t = " << i / 100.0;
    previous = luminance;
  }
}

TEST(ImageDiffTest, FalseColourMapsErrorMagnitude) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Error magnitudes (max over channels): 0, 1, 0.5, non-finite.
  const Image a = MakeImage2x2(Rgb(1), Rgb(0, 0, 1), Rgb(0.5f, 0, 0), Rgb(nan));
  const Image b = MakeImage2x2(Rgb(1), Rgb(0.5f, 0, 0), Rgb(0), Rgb(0));
  const Image automatic = FalseColourError(a, b, 0);
  EXPECT_EQ(automatic.at(0, 0), ErrorColormap(0));
  EXPECT_EQ(automatic.at(1, 0), ErrorColormap(1));
  EXPECT_EQ(automatic.at(0, 1), ErrorColormap(0.5));
  EXPECT_EQ(automatic.at(1, 1), Rgb(1, 0, 1));
  const Image scaled = FalseColourError(a, b, 2.0);
  EXPECT_EQ(scaled.at(1, 0), ErrorColormap(0.5));
  EXPECT_EQ(scaled.at(0, 1), ErrorColormap(0.25));
  // Identical images: everything at the bottom of the ramp, no division by zero.
  const Image same = FalseColourError(b, b);
  for (size_t i = 0; i < same.size(); ++i) EXPECT_EQ(same[i], ErrorColormap(0));
}

}  // namespace
}  // namespace pf

namespace pf {
namespace {

TEST(ImageDiffTest, ClampedRmseMeasuresTheDisplayRange) {
  Image a(2, 1), b(2, 1);
  a[0] = Rgb(20.0f);  // a light pixel, wrongly estimated: counts only up to 1
  b[0] = Rgb(0.5f);
  a[1] = Rgb(0.25f);
  b[1] = Rgb(0.5f);
  const ImageDiffStats d = CompareImages(a, b);
  EXPECT_NEAR(d.rmse_clamped, std::sqrt((0.25 + 0.0625) / 2.0), 1e-9);
  EXPECT_GT(d.rmse, 13.0);
}

}  // namespace
}  // namespace pf

namespace pf {
namespace {

TEST(ImageDiffTest, DisplayRmseIsRelativeToTheReferencesWhite) {
  // Grey 0.09 everywhere (median 0.09 = middle grey 0.18 of white): white is 0.5.
  Image reference(10, 10);
  for (Rgb& c : reference.pixels()) c = Rgb(0.09f);
  Image a = reference;
  a[0] = Rgb(20.0f);  // counts as 0.5: an error of 0.41 = 0.82 of white
  a[1] = Rgb(0.19f);  // 0.1 = 0.2 of white
  const ImageDiffStats d = CompareImages(a, reference);
  EXPECT_NEAR(d.display_white, 0.5, 1e-6);
  EXPECT_NEAR(d.rmse_display, std::sqrt((0.82 * 0.82 + 0.2 * 0.2) / 100.0), 1e-6);
  // A light covering 30 % of the view does not move white (the median does not see it).
  Image lit = reference;
  for (size_t i = 0; i < 30; ++i) lit[i] = Rgb(50.0f);
  EXPECT_NEAR(DisplayWhite(lit), 0.5, 1e-6);
  // Scale-free: the same scene 100x dimmer has the same display RMSE.
  Image dim_a = a, dim_ref = reference;
  for (Rgb& c : dim_a.pixels()) c *= 0.01f;
  for (Rgb& c : dim_ref.pixels()) c *= 0.01f;
  EXPECT_NEAR(CompareImages(dim_a, dim_ref).rmse_display, d.rmse_display, 1e-6);
}

}  // namespace
}  // namespace pf
