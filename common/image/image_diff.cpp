#include "common/image/image_diff.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "common/core/error.h"

namespace pf {
namespace {

void CheckSameSize(const Image& a, const Image& reference) {
  if (a.width() != reference.width() || a.height() != reference.height()) {
    throw InputError("cannot compare images of different sizes: " + std::to_string(a.width()) + "x" +
                     std::to_string(a.height()) + " vs reference " + std::to_string(reference.width()) + "x" +
                     std::to_string(reference.height()));
  }
}

double SrgbToLinear(double v) {
  return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}

}  // namespace

double DisplayWhite(const Image& image) {
  constexpr double kKey = 0.18;
  std::vector<float> luminance;
  luminance.reserve(image.size());
  double sum = 0;
  for (const Rgb& c : image.pixels()) {
    if (!c.IsFinite()) continue;
    luminance.push_back(std::max(0.0f, c.Luminance()));
    sum += luminance.back();
  }
  if (luminance.empty()) return 1.0;
  const auto middle = luminance.begin() + luminance.size() / 2;
  std::nth_element(luminance.begin(), middle, luminance.end());
  if (*middle > 0) return *middle / kKey;
  return sum > 0 ? sum / double(luminance.size()) / kKey : 1.0;
}

std::vector<uint8_t> EmitterExclusionMask(const std::vector<float>& coverage, int width, int height,
                                          int band) {
  if (coverage.size() != size_t(width) * size_t(height))
    throw InputError("emitter coverage: " + std::to_string(coverage.size()) + " values for a " +
                     std::to_string(width) + "x" + std::to_string(height) + " image");
  std::vector<uint8_t> mask(coverage.size(), 0);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      if (!(coverage[size_t(y) * width + x] > 0.0f)) continue;
      for (int yy = std::max(0, y - band); yy <= std::min(height - 1, y + band); ++yy)
        for (int xx = std::max(0, x - band); xx <= std::min(width - 1, x + band); ++xx)
          mask[size_t(yy) * width + xx] = 1;
    }
  return mask;
}

double RmseOver(const Image& a, const Image& reference, const std::vector<uint8_t>& selected) {
  CheckSameSize(a, reference);
  if (selected.size() != a.size()) throw InputError("RmseOver: selection size differs from the image size");
  double sum = 0;
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!selected[i] || !a[i].IsFinite() || !reference[i].IsFinite()) continue;
    for (int c = 0; c < 3; ++c) {
      const double d = double(a[i][c]) - reference[i][c];
      sum += d * d;
    }
    ++n;
  }
  return n > 0 ? std::sqrt(sum / (3.0 * double(n))) : 0.0;
}

namespace {

void AddMaskedMetrics(const Image& a, const Image& reference, const std::vector<uint8_t>& excluded,
                      ImageDiffStats* stats) {
  if (excluded.size() != a.size())
    throw InputError("exclusion mask: " + std::to_string(excluded.size()) + " values for " +
                     std::to_string(a.size()) + " pixels");
  std::vector<uint8_t> kept(excluded.size());
  for (size_t i = 0; i < kept.size(); ++i)
    kept[i] = !excluded[i] && a[i].IsFinite() && reference[i].IsFinite();
  stats->masked = true;
  stats->rmse_masked = RmseOver(a, reference, kept);
  stats->pixels_masked = size_t(std::count(kept.begin(), kept.end(), uint8_t(1)));
  double sum_a = 0, sum_b = 0;
  for (size_t i = 0; i < kept.size(); ++i)
    if (kept[i]) {
      sum_a += (double(a[i].r) + a[i].g + a[i].b) / 3.0;
      sum_b += (double(reference[i].r) + reference[i].g + reference[i].b) / 3.0;
    }
  if (stats->pixels_masked > 0) {
    stats->mean_masked_a = sum_a / double(stats->pixels_masked);
    stats->mean_masked_b = sum_b / double(stats->pixels_masked);
  }
  constexpr int kB = kLowFrequencyBlock;
  double sum = 0;
  size_t blocks = 0;
  for (int by = 0; by + kB <= a.height(); by += kB)
    for (int bx = 0; bx + kB <= a.width(); bx += kB) {
      double da[3] = {0, 0, 0};
      bool whole = true;
      for (int y = by; y < by + kB && whole; ++y)
        for (int x = bx; x < bx + kB; ++x) {
          const size_t i = size_t(y) * a.width() + x;
          if (!kept[i]) {
            whole = false;
            break;
          }
          for (int c = 0; c < 3; ++c) da[c] += double(a[i][c]) - reference[i][c];
        }
      if (!whole) continue;
      for (int c = 0; c < 3; ++c) sum += (da[c] / (kB * kB)) * (da[c] / (kB * kB));
      ++blocks;
    }
  stats->blocks_lowfreq = blocks;
  stats->rmse_lowfreq = blocks > 0 ? std::sqrt(sum / (3.0 * double(blocks))) : 0.0;
}

}  // namespace

ImageDiffStats CompareImages(const Image& a, const Image& reference, const std::vector<uint8_t>* excluded) {
  CheckSameSize(a, reference);
  ImageDiffStats stats;
  double sum_squared = 0, sum_relative = 0, sum_a = 0, sum_b = 0;
  double sum_clamped = 0, sum_display = 0;
  const double white = DisplayWhite(reference);
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      const Rgb& pa = a.at(x, y);
      const Rgb& pb = reference.at(x, y);
      const bool finite_a = pa.IsFinite(), finite_b = pb.IsFinite();
      stats.nonfinite_a += !finite_a;
      stats.nonfinite_b += !finite_b;
      if (!finite_a || !finite_b) continue;
      ++stats.pixels;
      for (int c = 0; c < 3; ++c) {
        const double va = pa[c], vb = pb[c];
        const double d = va - vb;
        sum_squared += d * d;
        const double dc = std::clamp(va, 0.0, 1.0) - std::clamp(vb, 0.0, 1.0);
        sum_clamped += dc * dc;
        const double dd = std::clamp(va, 0.0, white) - std::clamp(vb, 0.0, white);
        sum_display += dd * dd;
        sum_relative += d * d / (vb * vb + kRelativeMseEpsilon);
        sum_a += va;
        sum_b += vb;
        if (stats.max_x < 0 || std::abs(d) > stats.max_abs_error) {
          stats.max_abs_error = std::abs(d);
          stats.max_x = x;
          stats.max_y = y;
        }
      }
    }
  }
  if (excluded) AddMaskedMetrics(a, reference, *excluded, &stats);
  if (stats.pixels == 0) return stats;
  const double n = 3.0 * double(stats.pixels);
  stats.rmse = std::sqrt(sum_squared / n);
  stats.rmse_clamped = std::sqrt(sum_clamped / n);
  stats.display_white = white;
  stats.rmse_display = std::sqrt(sum_display / n) / white;
  stats.relative_mse = sum_relative / n;
  stats.mean_a = sum_a / n;
  stats.mean_b = sum_b / n;
  return stats;
}

Rgb ErrorColormap(double t) {
  // viridis at t = 0, 1/4, 1/2, 3/4, 1 (#440154 #3b528b #21918c #5ec962 #fde725), sRGB.
  static constexpr double kStops[5][3] = {
      {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
  t = std::isnan(t) ? 0.0 : std::clamp(t, 0.0, 1.0);
  const double s = t * 4.0;
  const int i = std::min(int(s), 3);
  const double f = s - i;
  Rgb out;
  for (int c = 0; c < 3; ++c) {
    const double srgb = (kStops[i][c] + f * (kStops[i + 1][c] - kStops[i][c])) / 255.0;
    out[c] = float(SrgbToLinear(srgb));
  }
  return out;
}

Image FalseColourError(const Image& a, const Image& reference, double scale) {
  CheckSameSize(a, reference);
  Image error_image(a.width(), a.height());
  std::vector<double> magnitude(a.size(), -1.0);  // -1 marks a non-finite pixel
  double max_magnitude = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (!a[i].IsFinite() || !reference[i].IsFinite()) continue;
    double m = 0;
    for (int c = 0; c < 3; ++c) m = std::max(m, std::abs(double(a[i][c]) - reference[i][c]));
    magnitude[i] = m;
    max_magnitude = std::max(max_magnitude, m);
  }
  if (!(scale > 0)) scale = max_magnitude;
  for (size_t i = 0; i < a.size(); ++i) {
    if (magnitude[i] < 0) {
      error_image[i] = Rgb(1, 0, 1);
    } else {
      error_image[i] = ErrorColormap(scale > 0 ? magnitude[i] / scale : 0.0);
    }
  }
  return error_image;
}

}  // namespace pf
