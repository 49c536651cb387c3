#pragma once
// Linear float RGB image, row-major, (0,0) = top-left. The only place that includes OpenEXR
// is image/exr_io.cpp; PNG goes through libpng in image/png_io.cpp.

#include <map>
#include <string>
#include <vector>

#include "common/core/math.h"

namespace pf {

class Image {
 public:
  Image() = default;
  Image(int width, int height) : width_(width), height_(height), pixels_(size_t(width) * height) {}

  int width() const { return width_; }
  int height() const { return height_; }
  size_t size() const { return pixels_.size(); }
  Rgb& at(int x, int y) { return pixels_[size_t(y) * width_ + x]; }
  const Rgb& at(int x, int y) const { return pixels_[size_t(y) * width_ + x]; }
  Rgb& operator[](size_t i) { return pixels_[i]; }
  const Rgb& operator[](size_t i) const { return pixels_[i]; }
  std::vector<Rgb>& pixels() { return pixels_; }
  const std::vector<Rgb>& pixels() const { return pixels_; }

 private:
  int width_ = 0, height_ = 0;
  std::vector<Rgb> pixels_;
};

// Free-form metadata stored in the EXR header as string attributes (render settings, spp,
// time, seed...). Keys are prefixed "pf:" in the file.
using ImageMetadata = std::map<std::string, std::string>;

}  // namespace pf
