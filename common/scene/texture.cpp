// Texture lookup (texture.h).
#include "common/scene/texture.h"

#include <cmath>

namespace pf {

int WrapTexelIndex(int64_t i, int size, TextureWrap wrap) {
  const int64_t n = size;
  switch (wrap) {
    case TextureWrap::kClampToEdge:
      return int(i < 0 ? 0 : i >= n ? n - 1 : i);
    case TextureWrap::kMirroredRepeat: {
      // Period 2n: 0..n−1 forwards, then n−1..0 (the edge texel repeats at each mirror).
      int64_t m = i % (2 * n);
      if (m < 0) m += 2 * n;
      return int(m < n ? m : 2 * n - 1 - m);
    }
    case TextureWrap::kRepeat:
    default: {
      int64_t m = i % n;
      if (m < 0) m += n;
      return int(m);
    }
  }
}

Rgb Texture::Lookup(const TextureCoordinates& uv) const {
  const Image& im = *image;
  const int w = im.width(), h = im.height();
  if (!std::isfinite(uv[0]) || !std::isfinite(uv[1])) return im.at(0, 0);
  // Texel centres sit at (i + ½)/size (texture.h); in double so that large repeat counts keep
  // their fraction.
  const double x = double(uv[0]) * w - 0.5, y = double(uv[1]) * h - 0.5;
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const float tx = float(x - fx0), ty = float(y - fy0);
  const int64_t ix = int64_t(fx0), iy = int64_t(fy0);
  const int x0 = WrapTexelIndex(ix, w, wrap_u), x1 = WrapTexelIndex(ix + 1, w, wrap_u);
  const int y0 = WrapTexelIndex(iy, h, wrap_v), y1 = WrapTexelIndex(iy + 1, h, wrap_v);
  const Rgb top = im.at(x0, y0) * (1.0f - tx) + im.at(x1, y0) * tx;
  const Rgb bottom = im.at(x0, y1) * (1.0f - tx) + im.at(x1, y1) * tx;
  return top * (1.0f - ty) + bottom * ty;
}

}  // namespace pf
