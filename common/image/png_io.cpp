// libpng wrapper (see png_io.h). Uses libpng's "simplified" API, which handles libpng's
// setjmp/longjmp error handling internally and reports failures as return codes, so no
// longjmp ever crosses C++ frames.

#include "common/image/png_io.h"

#include <png.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <string_view>
#include <system_error>

#include "common/core/atomic_file.h"
#include "common/core/error.h"

namespace pf {
namespace {

void CheckNotEmpty(const Image& image) {
  if (image.width() <= 0 || image.height() <= 0) {
    throw InputError("cannot write an empty image (" + std::to_string(image.width()) + "x" +
                     std::to_string(image.height()) + ") as PNG");
  }
}

}  // namespace

double AutoExposureScale(const Image& image) {
  std::vector<float> luminance;
  luminance.reserve(image.size());
  for (const Rgb& c : image.pixels()) {
    if (c.IsFinite()) luminance.push_back(std::max(0.0f, c.Luminance()));
  }
  if (luminance.empty()) return 1.0;
  const size_t rank = size_t(0.99 * double(luminance.size() - 1));
  std::nth_element(luminance.begin(), luminance.begin() + rank, luminance.end());
  double reference = luminance[rank];
  if (reference <= 0) reference = *std::max_element(luminance.begin() + rank, luminance.end());
  return reference > 0 ? kAutoExposureTarget / reference : 1.0;
}

double PreviewScale(const Image& image, const PreviewOptions& options) {
  const double scale = std::exp2(options.exposure_stops);
  return options.auto_exposure ? scale * AutoExposureScale(image) : scale;
}

double SrgbOetf(double v) {
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

std::vector<uint8_t> ToneMapToSrgb8(const Image& image, const PreviewOptions& options) {
  const double scale = PreviewScale(image, options);
  std::vector<uint8_t> bytes(image.size() * 3);
  for (size_t i = 0; i < image.size(); ++i) {
    for (int c = 0; c < 3; ++c) {
      const double linear = double(image[i][c]) * scale;
      // NaN fails both comparisons and becomes 0; infinities clamp to the ends.
      const double v = linear > 0 ? std::min(linear, 1.0) : 0.0;
      bytes[3 * i + c] = uint8_t(std::lround(255.0 * SrgbOetf(v)));
    }
  }
  return bytes;
}

std::string EncodePngPreview(const Image& image, const PreviewOptions& options) {
  CheckNotEmpty(image);
  const std::vector<uint8_t> pixels = ToneMapToSrgb8(image, options);
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  png.width = png_uint_32(image.width());
  png.height = png_uint_32(image.height());
  png.format = PNG_FORMAT_RGB;  // 8-bit, non-linear: libpng writes an sRGB chunk
  // One pass into a buffer of the worst-case size, then trim.
  std::string out(PNG_IMAGE_PNG_SIZE_MAX(png), '\0');
  png_alloc_size_t size = out.size();
  const int ok = png_image_write_to_memory(&png, out.data(), &size, /*convert_to_8_bit=*/0, pixels.data(),
                                           /*row_stride=*/0,
                                           /*colormap=*/nullptr);
  if (!ok) {
    const std::string reason = png.message;
    png_image_free(&png);
    throw SystemError("cannot encode PNG preview: " + reason);
  }
  out.resize(size);
  return out;
}

void WritePngPreview(const std::filesystem::path& path, const Image& image, const PreviewOptions& options) {
  std::string bytes;
  try {
    bytes = EncodePngPreview(image, options);
  } catch (const SystemError& e) {
    throw SystemError(path.string() + ": " + e.what());
  }
  WriteFileAtomically(path, bytes);
}

Png8Image ReadPng8(const std::filesystem::path& path) {
  png_image png{};
  png.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&png, path.c_str())) {
    const std::string reason = png.message;
    png_image_free(&png);
    throw SystemError(path.string() + ": cannot read PNG: " + reason);
  }
  png.format = PNG_FORMAT_RGB;
  Png8Image result;
  result.width = int(png.width);
  result.height = int(png.height);
  result.rgb.resize(PNG_IMAGE_SIZE(png));
  const png_color black{0, 0, 0};
  if (!png_image_finish_read(&png, &black, result.rgb.data(), /*row_stride=*/0,
                             /*colormap=*/nullptr)) {
    const std::string reason = png.message;
    png_image_free(&png);
    throw SystemError(path.string() + ": cannot read PNG: " + reason);
  }
  return result;
}

}  // namespace pf
