#pragma once
// OpenEXR reading and writing of linear float RGB images. This file pair is the only place in
// photonfarm that includes OpenEXR headers; every OpenEXR exception is caught here and rethrown
// as pf::SystemError carrying the path (or "<memory>") and the library's reason.
//
// Files written here hold three FLOAT channels R, G, B with data window == display window ==
// [0, width) x [0, height), plus one string attribute "pf:<key>" per metadata entry.

#include <filesystem>
#include <string>
#include <string_view>
#include <utility>

#include "common/image/image.h"

namespace pf {

// Lossless compressions offered for output. kZip (zlib over 16 scanlines) is the everyday
// default; kPiz (wavelet + Huffman) usually compresses noisy float renders better and suits
// the kept reference images; kNone writes raw floats (fastest, largest).
enum class ExrCompression { kNone, kZip, kPiz };

// Writes `image` to `path` atomically: the bytes go to "<path>.tmp.<pid>" in the same
// directory, which is flushed to disk and then renamed over `path`, so a reader (e.g. a viewer
// watching a progressively rewritten output) sees either the old or the new file, never a
// partial one. Two threads of one process must not write the same path at the same time.
// Throws InputError for an empty image and SystemError if encoding or the file system fails
// (the temporary file is removed in that case).
void WriteExr(const std::filesystem::path& path, const Image& image, const ImageMetadata& metadata = {},
              ExrCompression compression = ExrCompression::kZip);

// Reads the R, G and B channels of a scanline or tiled EXR (single part, or the first part of
// a multi-part file) of any pixel type (HALF, FLOAT, UINT), converting to float. The returned
// image covers the display window; pixels of the data window outside it are dropped and
// display-window pixels without data are black, so an image rendered with a crop region lines
// up with a full-frame reference. If `metadata` is non-null it receives every string
// attribute named "pf:<key>" (prefix stripped); other attributes are ignored.
// Throws SystemError naming the path if the file is missing or unreadable, is not an EXR, is
// truncated or corrupt, lacks one of R, G, B, has subsampled R/G/B channels, or has a window
// larger than kMaxExrPixels.
Image ReadExr(const std::filesystem::path& path, ImageMetadata* metadata = nullptr);

// The windows of an EXR file, from its header alone (pixels unread): ReadExr allocates the data
// window, and the display window too where they differ (it returns the display window).
// SystemError as ReadExr, also for a window larger than kMaxExrPixels.
struct ExrWindows {
  int data_width = 0, data_height = 0;
  int display_width = 0, display_height = 0;
  bool same = true;  // the data window is the display window
};
ExrWindows ReadExrWindows(const std::filesystem::path& path);

// The same encoding as WriteExr, into memory (e.g. for sending over gRPC). Deterministic: the
// same image, metadata and compression give the same bytes.
std::string EncodeExrToMemory(const Image& image, const ImageMetadata& metadata = {},
                              ExrCompression compression = ExrCompression::kZip);

// The same decoding as ReadExr, from memory. Errors name the source as "<memory>".
Image DecodeExrFromMemory(std::string_view bytes, ImageMetadata* metadata = nullptr);

// Upper bound on the number of pixels of a window we agree to allocate when reading (guards
// against corrupt or hostile headers): 2^28 pixels = 3 GiB of float RGB, e.g. 16384 x 16384.
inline constexpr long long kMaxExrPixels = 1LL << 28;

// Prefix of the EXR attribute names that carry ImageMetadata entries.
inline constexpr std::string_view kExrMetadataPrefix = "pf:";

}  // namespace pf
