#pragma once
// 8-bit sRGB PNG previews of linear float images. This file pair is the only place that
// includes libpng. PNG is for looking at; the data of record is the EXR (exr_io.h).
//
// Tone mapping, per channel, deterministic (no dithering):
//   scale = 2^exposure_stops * (auto_exposure ? AutoExposureScale(image) : 1)
//   v     = clamp(scale * linear, 0, 1)     (NaN -> 0, +inf -> 1)
//   byte  = round(255 * OETF(v))            (sRGB OETF, IEC 61966-2-1)
// The PNG carries an sRGB chunk.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/image/image.h"

namespace pf {

struct PreviewOptions {
  // Exposure adjustment in stops: linear values are multiplied by 2^exposure_stops.
  double exposure_stops = 0.0;
  // If true, first scale so that the 99th-percentile luminance maps to kAutoExposureTarget
  // (see AutoExposureScale); exposure_stops then applies on top.
  bool auto_exposure = false;
};

inline constexpr double kAutoExposureTarget = 0.9;

// The linear multiplier used by auto exposure: kAutoExposureTarget / L99, where L99 is the
// 99th percentile (nearest rank below: element floor(0.99 (n - 1)) of the sorted values) of
// the Rec. 709 luminance over the n finite pixels, negative luminances counted as 0. If L99 is
// 0 (mostly black image) the maximum luminance is used instead; if that is 0 too, or there
// are no finite pixels, the scale is 1.
double AutoExposureScale(const Image& image);

// The linear multiplier PreviewOptions implies for `image`.
double PreviewScale(const Image& image, const PreviewOptions& options);

// sRGB opto-electronic transfer function for v in [0, 1].
double SrgbOetf(double v);

// Tone maps to interleaved 8-bit sRGB, row-major, 3 bytes per pixel (the PNG's pixels).
std::vector<uint8_t> ToneMapToSrgb8(const Image& image, const PreviewOptions& options = {});

// PNG bytes of the preview (e.g. for sending over gRPC). Throws InputError for an empty
// image, SystemError if libpng fails.
std::string EncodePngPreview(const Image& image, const PreviewOptions& options = {});

// Writes the preview atomically ("<path>.tmp.<pid>" then rename, as WriteExr does).
// Throws InputError for an empty image, SystemError naming the path on failure.
void WritePngPreview(const std::filesystem::path& path, const Image& image,
                     const PreviewOptions& options = {});

// A decoded 8-bit RGB PNG: width * height * 3 bytes, row-major, top row first.
struct Png8Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgb;
};

// Reads any PNG as 8-bit RGB (for tests and tools; libpng converts other formats: alpha is
// composited on black, 16-bit and non-sRGB-gamma data are converted to 8-bit sRGB). Throws SystemError naming
// the path if the file is missing or not a valid PNG.
Png8Image ReadPng8(const std::filesystem::path& path);

}  // namespace pf
