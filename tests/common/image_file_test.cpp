// ReadLinearImage (common/image/image_file.h): each format's pixels as linear RGB, the sRGB decode
// of 8-bit files, and every bad input an InputError naming the file.
#include "common/image/image_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stb/stb_image_write.h>

#include <ImathBox.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "common/image/exr_io.h"
#include "tests/util/temp_dir.h"

namespace pf {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class ImageFileTest : public test_util::TempDirTest {
 protected:
  // The bytes of `path` after `write` made it.
  template <typename Write>
  static std::string ReadFile(const fs::path& path, Write write) {
    write();
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  // The InputError message ReadLinearImage gives for `path` ("" and a failure if none).
  static std::string ErrorOf(const fs::path& path) {
    try {
      ReadLinearImage(path);
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << path << " was read";
    return "";
  }
};

TEST_F(ImageFileTest, HdrIsLinearFloat) {
  const std::vector<float> rgb = {0.25f, 1.5f, 1000.0f, 0.0f, 0.5f, 2.0f};
  const fs::path path = dir_ / "sky.hdr";
  ASSERT_TRUE(stbi_write_hdr(path.c_str(), 2, 1, 3, rgb.data()));
  const Image img = ReadLinearImage(path);
  ASSERT_EQ(img.width(), 2);
  ASSERT_EQ(img.height(), 1);
  // RGBE keeps 8 bits of mantissa per channel, relative to the largest channel.
  EXPECT_NEAR(img.at(0, 0).r, 0.25f, 1000.0f / 256);
  EXPECT_NEAR(img.at(0, 0).b, 1000.0f, 1000.0f / 256);
  EXPECT_NEAR(img.at(1, 0).g, 0.5f, 2.0f / 256);
  EXPECT_NEAR(img.at(1, 0).b, 2.0f, 2.0f / 256);
}

TEST_F(ImageFileTest, EightBitPngIsSrgbDecoded) {
  const unsigned char pixels[] = {0, 128, 255, 10, 10, 10};
  const fs::path path = dir_ / "tex.png";
  ASSERT_TRUE(stbi_write_png(path.c_str(), 2, 1, 3, pixels, 6));
  const Image img = ReadLinearImage(path);
  EXPECT_EQ(img.at(0, 0).r, 0.0f);
  EXPECT_NEAR(img.at(0, 0).g, 0.2158605, 1e-6);  // ((128/255 + 0.055)/1.055)^2.4
  EXPECT_EQ(img.at(0, 0).b, 1.0f);
  EXPECT_NEAR(img.at(1, 0).r, 10.0 / 255 / 12.92, 1e-7);  // the linear segment
}

TEST_F(ImageFileTest, GreyJpegIsReplicated) {
  const unsigned char pixels[] = {200, 200, 200, 200};
  const fs::path path = dir_ / "grey.jpg";
  ASSERT_TRUE(stbi_write_jpg(path.c_str(), 2, 2, 1, pixels, 100));
  const Image img = ReadLinearImage(path);
  EXPECT_NEAR(img.at(1, 1).r, SrgbToLinear8(200), 0.02);
  EXPECT_EQ(img.at(1, 1).r, img.at(1, 1).b);
}

TEST_F(ImageFileTest, ExrGoesThroughTheExrReader) {
  Image img(3, 2);
  img.at(2, 1) = Rgb(7.0f, 8.0f, 9.0f);
  WriteExr(dir_ / "sky.exr", img);
  const Image back = ReadLinearImage(dir_ / "sky.exr");
  EXPECT_EQ(back.at(2, 1).g, 8.0f);
}

TEST_F(ImageFileTest, BadInputNamesTheFile) {
  EXPECT_THAT(ErrorOf(dir_ / "missing.hdr"), HasSubstr("missing.hdr: image file not found"));
  tmp_.Write("corrupt.hdr", "#?RADIANCE\nthis is not an image");
  EXPECT_THAT(ErrorOf(dir_ / "corrupt.hdr"), HasSubstr("corrupt.hdr: cannot decode the image"));
  tmp_.Write("corrupt.exr", "not an exr at all");
  EXPECT_THAT(ErrorOf(dir_ / "corrupt.exr"), HasSubstr("corrupt.exr: cannot read the EXR image"));
  tmp_.Write("image.tga", "x");
  EXPECT_THAT(ErrorOf(dir_ / "image.tga"), HasSubstr("unsupported image extension '.tga'"));
  Image nan(2, 2);
  nan.at(1, 0) = Rgb(1.0f, std::numeric_limits<float>::quiet_NaN(), 0.0f);
  WriteExr(dir_ / "nan.exr", nan);
  EXPECT_THAT(ErrorOf(dir_ / "nan.exr"),
              HasSubstr("nan.exr: pixel (1, 0) is not a finite non-negative colour"));
  Image negative(2, 2);
  negative.at(0, 1) = Rgb(-1.0f, 0.0f, 0.0f);
  WriteExr(dir_ / "negative.exr", negative);
  EXPECT_THAT(ErrorOf(dir_ / "negative.exr"), HasSubstr("pixel (0, 1) is not a finite non-negative colour"));
}

// A header claiming 100000 × 100000 pixels is refused before any pixel is decoded.
TEST_F(ImageFileTest, OversizedImageIsRefusedFromItsHeader) {
  tmp_.Write("huge.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 100000\n");
  try {
    ReadLinearImage(dir_ / "huge.hdr");
    ADD_FAILURE() << "read";
  } catch (const LimitError& e) {
    EXPECT_THAT(std::string(e.what()),
                HasSubstr("huge.hdr: image of 100000x100000 pixels exceeds the limit"));
  }
}

// The pixels of all images of one load: each image is charged from its header (a header without
// any pixel data behind it is enough), the first one past the allowance is refused naming it and
// the budget, and the ones before it stay charged.
TEST_F(ImageFileTest, AnAllowanceCountsThePixelsOfEveryImageFromTheirHeaders) {
  tmp_.Write("a.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2000 +X 2000\n");
  tmp_.Write("b.hdr", "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2000 +X 1500\n");
  PixelAllowance allowance(6'000'000);
  // a.hdr: 4 M pixels fit, so it is decoded (stb_image decides what a file without pixel data
  // gives; only a LimitError would be wrong here).
  try {
    ReadLinearImage(dir_ / "a.hdr", &allowance);
  } catch (const LimitError& e) {
    ADD_FAILURE() << e.what();
  } catch (const InputError&) {
  }
  EXPECT_EQ(allowance.used(), 4'000'000u);
  try {
    ReadLinearImage(dir_ / "b.hdr", &allowance);
    ADD_FAILURE() << "read";
  } catch (const LimitError& e) {
    EXPECT_THAT(std::string(e.what()),
                HasSubstr("b.hdr: image of 1500x2000 pixels would bring the scene's images "
                          "to 7000000 pixels, more than the budget of 6000000"));
  }
  EXPECT_EQ(allowance.used(), 4'000'000u);
  // An EXR's header is read alone first, in memory too the same allowance applies.
  Image small(3, 2);
  WriteExr(dir_ / "small.exr", small);
  PixelAllowance five(5);
  EXPECT_THROW(ReadLinearImage(dir_ / "small.exr", &five), LimitError);
  EXPECT_EQ(five.used(), 0u);
  PixelAllowance six(6);
  EXPECT_EQ(ReadLinearImage(dir_ / "small.exr", &six).width(), 3);
  EXPECT_EQ(six.used(), 6u);
  const std::string png = ReadFile(dir_ / "small.png", [&] {
    const unsigned char pixels[12] = {};
    EXPECT_TRUE(stbi_write_png((dir_ / "small.png").c_str(), 2, 2, 3, pixels, 6));
  });
  PixelAllowance three(3);
  EXPECT_THROW(
      DecodeLinearImage(reinterpret_cast<const unsigned char*>(png.data()), png.size(), "mem", &three),
      LimitError);
}

// Charged before the pixels are decoded: a PNG with only its signature and header (8 x 8, no
// image data) is a LimitError past the allowance, not the decoding error it would be otherwise.
TEST_F(ImageFileTest, APngIsChargedFromItsHeaderBeforeItsPixels) {
  std::string png("\x89PNG\r\n\x1a\n", 8);
  png += std::string("\0\0\0\x0d", 4) + "IHDR" + std::string("\0\0\0\x08\0\0\0\x08\x08\x02\0\0\0", 13);
  png += std::string(4, '\0');  // the chunk's CRC (stb_image does not check it)
  const auto* bytes = reinterpret_cast<const unsigned char*>(png.data());
  PixelAllowance three(3);
  EXPECT_THROW(DecodeLinearImage(bytes, png.size(), "header-only.png", &three), LimitError);
  PixelAllowance enough(64);
  try {
    DecodeLinearImage(bytes, png.size(), "header-only.png", &enough);
    ADD_FAILURE() << "decoded";
  } catch (const LimitError& e) {
    ADD_FAILURE() << e.what();
  } catch (const InputError& e) {
    EXPECT_THAT(std::string(e.what()), HasSubstr("cannot decode the image"));
  }
  EXPECT_EQ(enough.used(), 64u);
}

// What an EXR allocates is its data window (and its display window where they differ): a 1 x 1
// image whose data window is 64 x 64 is charged 4097 pixels, not 1.
TEST_F(ImageFileTest, AnExrIsChargedForItsDataWindow) {
  const fs::path path = dir_ / "window.exr";
  {
    Imf::Header header(Imath::Box2i({0, 0}, {0, 0}), Imath::Box2i({0, 0}, {63, 63}));
    for (const char* c : {"R", "G", "B"}) header.channels().insert(c, Imf::Channel(Imf::FLOAT));
    std::vector<float> zeros(64 * 64, 0.0f);
    Imf::OutputFile out(path.c_str(), header);
    Imf::FrameBuffer fb;
    for (const char* c : {"R", "G", "B"})
      fb.insert(c, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(zeros.data()), sizeof(float),
                              64 * sizeof(float)));
    out.setFrameBuffer(fb);
    out.writePixels(64);
  }
  PixelAllowance small(4096);
  EXPECT_THROW(ReadLinearImage(path, &small), LimitError);
  PixelAllowance enough(4097);
  const Image image = ReadLinearImage(path, &enough);
  EXPECT_EQ(image.width(), 1);
  EXPECT_EQ(enough.used(), 4097u);
}

}  // namespace
}  // namespace pf
