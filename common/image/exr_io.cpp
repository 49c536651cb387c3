// OpenEXR wrapper (see exr_io.h). Encoding and decoding go through in-memory Imf::OStream /
// Imf::IStream subclasses so that files and gRPC payloads share one code path; files are then
// written atomically (common/core/atomic_file.h).

#include "common/image/exr_io.h"

#include <algorithm>
#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <mutex>
#include <stdexcept>
#include <system_error>
#include <utility>

#include <Iex.h>
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include "common/core/atomic_file.h"
#include "common/core/error.h"

namespace pf {
namespace {

static_assert(sizeof(Rgb) == 3 * sizeof(float), "Image pixels must be three packed floats");

constexpr const char* kMemorySourceName = "<memory>";
constexpr const char* kChannelNames[3] = {"R", "G", "B"};

// A problem we detect ourselves in an otherwise readable file; reported like OpenEXR's own
// exceptions by the wrappers below.
class ExrFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Runs `fn` (which calls OpenEXR) and turns any exception into a SystemError that names the
// source and the action, e.g. "out.exr: cannot read OpenEXR image: missing channel \"G\"".
template <typename Fn>
auto CatchOpenExr(const std::string& source, const char* action, Fn&& fn) {
  try {
    return fn();
  } catch (const InputError&) {
    throw;  // our own error about the caller's input, already explained
  } catch (const std::exception& e) {
    throw SystemError(source + ": cannot " + action + " OpenEXR image: " + e.what());
  }
}

// Growable in-memory output. OpenEXR seeks back after the pixels to fill in the line offset
// table, so writes may land anywhere inside (or extend) the buffer.
class MemoryOStream final : public Imf::OStream {
 public:
  MemoryOStream() : Imf::OStream(kMemorySourceName) {}

  void write(const char c[], int n) override {
    const size_t end = pos_ + size_t(n);
    if (end > data_.size()) data_.resize(end);
    std::memcpy(data_.data() + pos_, c, size_t(n));
    pos_ = end;
  }
  uint64_t tellp() override { return pos_; }
  void seekp(uint64_t pos) override { pos_ = size_t(pos); }

  std::string Take() { return std::move(data_); }

 private:
  std::string data_;
  size_t pos_ = 0;
};

// Read-only view of encoded bytes. Reading past the end throws, as Imf::IStream requires.
class MemoryIStream final : public Imf::IStream {
 public:
  explicit MemoryIStream(std::string_view data) : Imf::IStream(kMemorySourceName), data_(data) {}

  bool read(char c[], int n) override {
    if (n < 0 || pos_ > data_.size() || size_t(n) > data_.size() - pos_) {
      throw Iex::InputExc("unexpected end of data");
    }
    std::memcpy(c, data_.data() + pos_, size_t(n));
    pos_ += size_t(n);
    return pos_ < data_.size();
  }
  uint64_t tellg() override { return pos_; }
  void seekg(uint64_t pos) override { pos_ = size_t(pos); }

 private:
  std::string_view data_;
  size_t pos_ = 0;
};

Imf::Compression ToImf(ExrCompression compression) {
  switch (compression) {
    case ExrCompression::kNone:
      return Imf::NO_COMPRESSION;
    case ExrCompression::kZip:
      return Imf::ZIP_COMPRESSION;
    case ExrCompression::kPiz:
      return Imf::PIZ_COMPRESSION;
  }
  throw InputError("unknown ExrCompression value " + std::to_string(int(compression)));
}

std::string Encode(const Image& image, const ImageMetadata& metadata, ExrCompression compression) {
  if (image.width() <= 0 || image.height() <= 0) {
    throw InputError("cannot encode an empty image (" + std::to_string(image.width()) + "x" +
                     std::to_string(image.height()) + ") as OpenEXR");
  }
  Imf::Header header(image.width(), image.height());
  header.compression() = ToImf(compression);
  for (const char* name : kChannelNames) header.channels().insert(name, Imf::Channel(Imf::FLOAT));
  for (const auto& [key, value] : metadata) {
    header.insert(std::string(kExrMetadataPrefix) + key, Imf::StringAttribute(value));
  }

  // OpenEXR only reads through the slice pointers when writing.
  char* base = const_cast<char*>(reinterpret_cast<const char*>(image.pixels().data()));
  const size_t x_stride = sizeof(Rgb);
  const size_t y_stride = x_stride * size_t(image.width());
  Imf::FrameBuffer frame_buffer;
  for (int c = 0; c < 3; ++c) {
    frame_buffer.insert(kChannelNames[c],
                        Imf::Slice(Imf::FLOAT, base + c * sizeof(float), x_stride, y_stride));
  }

  MemoryOStream stream;
  {
    // The line offset table is written when the OutputFile is destroyed.
    Imf::OutputFile file(stream, header);
    file.setFrameBuffer(frame_buffer);
    file.writePixels(image.height());
  }
  return stream.Take();
}

int64_t WindowWidth(const Imath::Box2i& box) {
  return int64_t(box.max.x) - box.min.x + 1;
}
int64_t WindowHeight(const Imath::Box2i& box) {
  return int64_t(box.max.y) - box.min.y + 1;
}

// OpenEXR sizes a file's line buffers and offset table from its header when the file is opened,
// before CheckWindow can look: its own header check refuses windows wider or taller than this
// first (every window CheckWindow accepts is far smaller in one of its sides).
void LimitHeaderSizes() {
  static std::once_flag once;
  std::call_once(once, [] {
    Imf::Header::setMaxImageSize(1 << 20, 1 << 20);
    Imf::Header::setMaxTileSize(1 << 20, 1 << 20);
  });
}

void CheckWindow(const Imath::Box2i& box, const char* what) {
  const int64_t w = WindowWidth(box), h = WindowHeight(box);
  if (w <= 0 || h <= 0 || w * h > kMaxExrPixels) {
    throw ExrFormatError(std::string(what) + " " + std::to_string(w) + "x" + std::to_string(h) +
                         " is empty or larger than " + std::to_string(kMaxExrPixels) + " pixels");
  }
}

Image Decode(Imf::InputFile& file, ImageMetadata* metadata) {
  const Imf::Header& header = file.header();
  for (const char* name : kChannelNames) {
    const Imf::Channel* channel = header.channels().findChannel(name);
    if (channel == nullptr) throw ExrFormatError(std::string("missing channel \"") + name + "\"");
    if (channel->xSampling != 1 || channel->ySampling != 1) {
      throw ExrFormatError(std::string("channel \"") + name + "\" is subsampled (unsupported)");
    }
  }
  const Imath::Box2i data_window = header.dataWindow();
  const Imath::Box2i display_window = header.displayWindow();
  CheckWindow(data_window, "data window");
  CheckWindow(display_window, "display window");

  Image data(int(WindowWidth(data_window)), int(WindowHeight(data_window)));
  char* base = reinterpret_cast<char*>(data.pixels().data());
  const size_t x_stride = sizeof(Rgb);
  const size_t y_stride = x_stride * size_t(data.width());
  Imf::FrameBuffer frame_buffer;
  for (int c = 0; c < 3; ++c) {
    // Slice::Make offsets the base pointer so that pixel (min.x, min.y) lands on `base`.
    frame_buffer.insert(kChannelNames[c], Imf::Slice::Make(Imf::FLOAT, base + c * sizeof(float), data_window,
                                                           x_stride, y_stride));
  }
  file.setFrameBuffer(frame_buffer);
  file.readPixels(data_window.min.y, data_window.max.y);

  if (metadata != nullptr) {
    ImageMetadata read;
    for (auto it = header.begin(); it != header.end(); ++it) {
      const std::string_view name = it.name();
      if (!name.starts_with(kExrMetadataPrefix)) continue;
      if (const auto* text = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
        read[std::string(name.substr(kExrMetadataPrefix.size()))] = text->value();
      }
    }
    *metadata = std::move(read);
  }

  if (data_window == display_window) return data;
  // Place the data window inside the display window: crop what lies outside, leave black
  // what has no data.
  Image out(int(WindowWidth(display_window)), int(WindowHeight(display_window)));
  const int x0 = std::max(data_window.min.x, display_window.min.x);
  const int x1 = std::min(data_window.max.x, display_window.max.x);
  const int y0 = std::max(data_window.min.y, display_window.min.y);
  const int y1 = std::min(data_window.max.y, display_window.max.y);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      out.at(x - display_window.min.x, y - display_window.min.y) =
          data.at(x - data_window.min.x, y - data_window.min.y);
    }
  }
  return out;
}

}  // namespace

void WriteExr(const std::filesystem::path& path, const Image& image, const ImageMetadata& metadata,
              ExrCompression compression) {
  const std::string bytes =
      CatchOpenExr(path.string(), "write", [&] { return Encode(image, metadata, compression); });
  WriteFileAtomically(path, bytes);
}

Image ReadExr(const std::filesystem::path& path, ImageMetadata* metadata) {
  return CatchOpenExr(path.string(), "read", [&] {
    LimitHeaderSizes();
    Imf::InputFile file(path.c_str());
    return Decode(file, metadata);
  });
}

ExrWindows ReadExrWindows(const std::filesystem::path& path) {
  return CatchOpenExr(path.string(), "read", [&] {
    LimitHeaderSizes();
    Imf::InputFile file(path.c_str());
    const Imath::Box2i data = file.header().dataWindow(), display = file.header().displayWindow();
    CheckWindow(data, "data window");
    CheckWindow(display, "display window");
    return ExrWindows{.data_width = int(WindowWidth(data)),
                      .data_height = int(WindowHeight(data)),
                      .display_width = int(WindowWidth(display)),
                      .display_height = int(WindowHeight(display)),
                      .same = data == display};
  });
}

std::string EncodeExrToMemory(const Image& image, const ImageMetadata& metadata, ExrCompression compression) {
  return CatchOpenExr(kMemorySourceName, "write", [&] { return Encode(image, metadata, compression); });
}

Image DecodeExrFromMemory(std::string_view bytes, ImageMetadata* metadata) {
  return CatchOpenExr(kMemorySourceName, "read", [&] {
    LimitHeaderSizes();
    MemoryIStream stream(bytes);
    Imf::InputFile file(stream);
    return Decode(file, metadata);
  });
}

}  // namespace pf
