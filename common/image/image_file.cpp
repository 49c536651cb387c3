#include "common/image/image_file.h"

#include <stb/stb_image.h>

#include <array>
#include <cctype>
#include <cmath>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <system_error>
#include <vector>

#include "common/core/error.h"
#include "common/image/exr_io.h"

namespace pf {
namespace {

std::string LowerExtension(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

[[noreturn]] void Fail(const std::filesystem::path& path, const std::string& reason) {
  throw InputError(SourceLocation{path.string(), 0}, reason);
}

void CheckSize(const std::filesystem::path& path, int width, int height, PixelAllowance* allowance) {
  if (width <= 0 || height <= 0) Fail(path, "the image has no pixels");
  if (width > kMaxImageFileSide || height > kMaxImageFileSide)
    throw LimitError(SourceLocation{path.string(), 0},
                     "image of " + std::to_string(width) + "x" + std::to_string(height) +
                         " pixels exceeds the limit of " + std::to_string(kMaxImageFileSide) + " per side");
  if (allowance != nullptr) allowance->Charge(path.string(), width, height);
}

struct StbFree {
  void operator()(void* p) const { stbi_image_free(p); }
};

// One pixel's channels (1..4 of them: grey, grey+alpha, RGB, RGBA) as linear RGB, and the
// alpha channel (channels 2 and 4) as `alpha(code)`.
template <typename T, typename Decode, typename Alpha>
ImageWithAlpha ToImage(const T* data, int width, int height, int channels, Decode decode, Alpha alpha) {
  ImageWithAlpha out{Image(width, height), {}};
  Image& image = out.rgb;
  const bool has_alpha = channels == 2 || channels == 4;
  if (has_alpha) out.alpha.resize(image.size());
  for (size_t i = 0; i < image.size(); ++i) {
    const T* p = data + i * size_t(channels);
    image[i] = channels >= 3 ? Rgb(decode(p[0]), decode(p[1]), decode(p[2])) : Rgb(decode(p[0]));
    if (has_alpha) out.alpha[i] = alpha(p[channels - 1]);
  }
  return out;
}

float Srgb16(stbi_us v) {
  const float c = float(v) / 65535.0f;
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}
float Linear16(stbi_us v) {
  return float(v) / 65535.0f;
}
float Linear8(stbi_uc v) {
  return float(v) / 255.0f;
}

// PNG, JPEG or Radiance HDR bytes through stb_image; `path` names them in messages.
ImageWithAlpha DecodeWithStb(const unsigned char* bytes, size_t size, const std::filesystem::path& path,
                             ImageCodes codes, PixelAllowance* allowance) {
  if (size > size_t(std::numeric_limits<int>::max())) Fail(path, "the image file is too large to decode");
  const int n = int(size);
  int width = 0, height = 0, channels = 0;
  // The header alone first: an oversized image is refused before its pixels are decoded.
  if (!stbi_info_from_memory(bytes, n, &width, &height, &channels))
    Fail(path, std::string("cannot decode the image: ") + stbi_failure_reason());
  CheckSize(path, width, height, allowance);
  // The decoders overwrite width and height: what they decode must be what was charged.
  const int header_width = width, header_height = height;
  const auto same_size = [&] {
    if (width != header_width || height != header_height)
      Fail(path, "cannot decode the image: its size differs from its header's");
  };
  if (stbi_is_hdr_from_memory(bytes, n)) {
    const std::unique_ptr<float, StbFree> data(
        stbi_loadf_from_memory(bytes, n, &width, &height, &channels, 0));
    if (!data) Fail(path, std::string("cannot decode the image: ") + stbi_failure_reason());
    same_size();
    const auto same = [](float v) { return v; };
    return ToImage(data.get(), width, height, channels, same, same);
  }
  const bool color = codes == ImageCodes::kColor;
  if (stbi_is_16_bit_from_memory(bytes, n)) {
    const std::unique_ptr<stbi_us, StbFree> data(
        stbi_load_16_from_memory(bytes, n, &width, &height, &channels, 0));
    if (!data) Fail(path, std::string("cannot decode the image: ") + stbi_failure_reason());
    same_size();
    return ToImage(data.get(), width, height, channels, color ? Srgb16 : Linear16, Linear16);
  }
  const std::unique_ptr<stbi_uc, StbFree> data(
      stbi_load_from_memory(bytes, n, &width, &height, &channels, 0));
  if (!data) Fail(path, std::string("cannot decode the image: ") + stbi_failure_reason());
  same_size();
  return ToImage(data.get(), width, height, channels, color ? SrgbToLinear8 : Linear8, Linear8);
}

ImageWithAlpha ReadWithStb(const std::filesystem::path& path, ImageCodes codes, PixelAllowance* allowance) {
  // The file is decoded from memory: a file larger than any image of the side limit could be is
  // refused before it is read.
  std::error_code ec;
  const uintmax_t bytes_on_disk = std::filesystem::file_size(path, ec);
  if (ec || bytes_on_disk > kMaxImageFileBytes)
    throw LimitError(
        SourceLocation{path.string(), 0},
        "image file larger than " + std::to_string(kMaxImageFileBytes >> 20) + " MiB (or unreadable)");
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
  if (!in.good() && !in.eof()) Fail(path, "cannot read the image file");
  return DecodeWithStb(bytes.data(), bytes.size(), path, codes, allowance);
}

// Every pixel a finite non-negative colour (an EXR or HDR can hold anything).
void CheckPixels(const Image& image, const std::filesystem::path& path) {
  for (int y = 0; y < image.height(); ++y)
    for (int x = 0; x < image.width(); ++x) {
      const Rgb& c = image.at(x, y);
      if (!c.IsFinite() || c[0] < 0.0f || c[1] < 0.0f || c[2] < 0.0f)
        Fail(path, "pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                       ") is not a finite non-negative colour");
    }
}

}  // namespace

void PixelAllowance::Charge(const std::string& source, int width, int height) {
  const uint64_t pixels = uint64_t(width) * uint64_t(height);
  if (pixels > limit_ - used_)
    throw LimitError(SourceLocation{source, 0},
                     "image of " + std::to_string(width) + "x" + std::to_string(height) +
                         " pixels would bring the scene's images to " + std::to_string(used_ + pixels) +
                         " pixels, more than the budget of " + std::to_string(limit_) +
                         " (SceneBudget::max_texels, docs/security.md)");
  used_ += pixels;
}

float SrgbToLinear8(unsigned char code) {
  static const auto table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) {
      const double c = i / 255.0;
      t[size_t(i)] = float(c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4));
    }
    return t;
  }();
  return table[code];
}

ImageWithAlpha ReadImageWithAlpha(const std::filesystem::path& path, ImageCodes codes,
                                  PixelAllowance* allowance) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) Fail(path, "image file not found (or not a regular file)");
  const std::string ext = LowerExtension(path);
  ImageWithAlpha image;
  if (ext == ".exr") {
    try {
      // The header first: the side limit and the allowance apply to what ReadExr allocates (the
      // data window, and the display window where they differ) before the pixels are read.
      const ExrWindows w = ReadExrWindows(path);
      CheckSize(path, w.data_width, w.data_height, allowance);
      if (!w.same) CheckSize(path, w.display_width, w.display_height, allowance);
      image.rgb = ReadExr(path);
      if (image.rgb.width() != w.display_width || image.rgb.height() != w.display_height)
        Fail(path, "the EXR image changed while it was read");
    } catch (const SystemError& e) {
      Fail(path, std::string("cannot read the EXR image: ") + e.what());
    }
  } else if (ext == ".hdr" || ext == ".png" || ext == ".jpg" || ext == ".jpeg") {
    image = ReadWithStb(path, codes, allowance);
  } else {
    Fail(path, "unsupported image extension '" + ext + "' (supported: .hdr, .exr, .png, .jpg, .jpeg)");
  }
  CheckPixels(image.rgb, path);
  return image;
}

Image ReadLinearImage(const std::filesystem::path& path, PixelAllowance* allowance) {
  return ReadImageWithAlpha(path, ImageCodes::kColor, allowance).rgb;
}

ImageWithAlpha DecodeImageWithAlpha(const unsigned char* bytes, size_t size, const std::string& name,
                                    ImageCodes codes, PixelAllowance* allowance) {
  if (size == 0) Fail(name, "the image holds no bytes");
  ImageWithAlpha image = DecodeWithStb(bytes, size, name, codes, allowance);
  CheckPixels(image.rgb, name);
  return image;
}

Image DecodeLinearImage(const unsigned char* bytes, size_t size, const std::string& name,
                        PixelAllowance* allowance) {
  return DecodeImageWithAlpha(bytes, size, name, ImageCodes::kColor, allowance).rgb;
}

}  // namespace pf
