#pragma once
// Reading an image file as linear float RGB, whatever its format: Radiance .hdr, PNG and JPEG
// through stb_image (Debian's compiled libstb), OpenEXR through exr_io.h. The one place scene
// inputs (an environment map, image textures) read pixels from, so that every one of them has
// the same formats, limits and messages.
//
// 8-bit and 16-bit PNG/JPEG are sRGB-encoded (IEC 61966-2-1) and decoded to linear; .hdr and .exr
// are linear already, unless the slot they serve holds data (ImageCodes::kData: glTF's
// metallicRoughnessTexture, a mask), whose codes are read linearly as code / max. Grey images
// are replicated to R = G = B. The alpha channel (grey+alpha, RGBA) is linear in every format
// (PNG's and glTF's convention); ReadLinearImage and DecodeLinearImage drop it.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "common/image/image.h"

namespace pf {

// Largest width or height accepted (and so at most 16384² pixels, 3 GiB of float RGB): a 100k²
// texture would take 120 GB; refused before its pixels are decoded.
inline constexpr int kMaxImageFileSide = 16384;
// Largest PNG, JPEG or HDR file read (they are decoded from memory): 1 GiB, more than an
// uncompressed 8-bit RGBA image of the side limit takes.
inline constexpr uintmax_t kMaxImageFileBytes = uintmax_t(1) << 30;

// What one scene load may still decode, in pixels summed over all its images (SceneBudget::
// max_texels, docs/security.md "Scene budgets"): images each within the side limit and small on
// disk (a 16384² PNG of one colour is 1 MB) must not together exhaust memory. Each image is
// charged from its header, before its pixels are decoded.
class PixelAllowance {
 public:
  explicit PixelAllowance(uint64_t pixels) : limit_(pixels) {}
  // Charges `pixels`, or throws LimitError naming `source`, the image's size and the budget.
  void Charge(const std::string& source, int width, int height);
  uint64_t used() const { return used_; }

 private:
  uint64_t limit_, used_ = 0;
};

// How an 8- or 16-bit PNG/JPEG code becomes a value: kColor by the sRGB curve (colour slots:
// glTF baseColor and emissive, OBJ map_Kd, environment maps), kData as code / max (data slots:
// glTF metallicRoughness, masks). HDR and EXR are linear either way.
enum class ImageCodes : uint8_t { kColor, kData };

// A decoded image and its alpha channel, row-major like its pixels; `alpha` is empty when the
// file has none (RGB, grey, HDR, EXR).
struct ImageWithAlpha {
  Image rgb;
  std::vector<float> alpha;
};

// Throws InputError naming the file: missing or unreadable, an unsupported extension, a corrupt
// or truncated file, a side above kMaxImageFileSide, a pixel that is not a finite non-negative
// colour (NaN, ±inf or negative values an EXR can hold); LimitError past `allowance` (null: none).
Image ReadLinearImage(const std::filesystem::path& path, PixelAllowance* allowance = nullptr);

// The same for an image held in memory (a glTF image in a buffer or a data: URI): PNG, JPEG or
// Radiance HDR, recognised by content; `name` stands for the file in messages
// ("scene.glb: images[0]").
Image DecodeLinearImage(const unsigned char* bytes, size_t size, const std::string& name,
                        PixelAllowance* allowance = nullptr);

// The same two with the codes read as `codes` says, and the alpha channel kept.
ImageWithAlpha ReadImageWithAlpha(const std::filesystem::path& path, ImageCodes codes,
                                  PixelAllowance* allowance = nullptr);
ImageWithAlpha DecodeImageWithAlpha(const unsigned char* bytes, size_t size, const std::string& name,
                                    ImageCodes codes, PixelAllowance* allowance = nullptr);

// The sRGB transfer function's inverse for one 8-bit code value (exact table lookup).
float SrgbToLinear8(unsigned char code);

}  // namespace pf
