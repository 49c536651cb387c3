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

namespace {

// The four texels around `uv` and their weights (texture.h: texel centres at (i + ½)/size).
struct Bilinear {
  size_t i00, i10, i01, i11;  // row-major indices: (x0, y0), (x1, y0), (x0, y1), (x1, y1)
  float tx, ty;
};

Bilinear Around(const TextureCoordinates& uv, int w, int h, TextureWrap wrap_u, TextureWrap wrap_v) {
  if (!std::isfinite(uv[0]) || !std::isfinite(uv[1])) return {0, 0, 0, 0, 0.0f, 0.0f};
  // In double so that large repeat counts keep their fraction.
  const double x = double(uv[0]) * w - 0.5, y = double(uv[1]) * h - 0.5;
  const double fx0 = std::floor(x), fy0 = std::floor(y);
  const int64_t ix = int64_t(fx0), iy = int64_t(fy0);
  const size_t x0 = size_t(WrapTexelIndex(ix, w, wrap_u)), x1 = size_t(WrapTexelIndex(ix + 1, w, wrap_u));
  const size_t y0 = size_t(WrapTexelIndex(iy, h, wrap_v)), y1 = size_t(WrapTexelIndex(iy + 1, h, wrap_v));
  const size_t row = size_t(w);
  return {y0 * row + x0, y0 * row + x1, y1 * row + x0, y1 * row + x1, float(x - fx0), float(y - fy0)};
}

}  // namespace

Rgb Texture::Lookup(const TextureCoordinates& uv) const {
  const Image& im = *image;
  const Bilinear b = Around(uv, im.width(), im.height(), wrap_u, wrap_v);
  const Rgb top = im[b.i00] * (1.0f - b.tx) + im[b.i10] * b.tx;
  const Rgb bottom = im[b.i01] * (1.0f - b.tx) + im[b.i11] * b.tx;
  return top * (1.0f - b.ty) + bottom * b.ty;
}

float Texture::LookupAlpha(const TextureCoordinates& uv) const {
  if (!alpha) return 1.0f;
  const std::vector<float>& a = *alpha;
  const Bilinear b = Around(uv, image->width(), image->height(), wrap_u, wrap_v);
  const float top = a[b.i00] * (1.0f - b.tx) + a[b.i10] * b.tx;
  const float bottom = a[b.i01] * (1.0f - b.tx) + a[b.i11] * b.tx;
  return top * (1.0f - b.ty) + bottom * b.ty;
}

}  // namespace pf
