#include "common/plan/progressive_bias.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/core/error.h"
#include "common/image/image.h"

namespace pf {

ProgressiveBias::ProgressiveBias(double alpha, int width, int height)
    : alpha_(alpha),
      width_(width),
      height_(height),
      blocks_x_(int((uint32_t(width) + kBiasBlockSide - 1) / kBiasBlockSide)),
      blocks_y_(int((uint32_t(height) + kBiasBlockSide - 1) / kBiasBlockSide)),
      fits_(size_t(blocks_x_) * size_t(blocks_y_)),
      passes_(size_t(width) * size_t(height), 0),
      sum_(size_t(width) * size_t(height), 0.0),
      sum2_(size_t(width) * size_t(height), 0.0) {
  if (!(alpha > 0.0 && alpha < 1.0)) throw InputError("progressive bias: alpha must be in (0, 1)");
}

void ProgressiveBias::Add(uint64_t pass, std::span<const uint32_t> pixels, std::span<const float> rgb_sums,
                          uint32_t samples) {
  if (samples == 0 || pixels.empty()) return;
  // x_p = r_p² / r_1² (render/progressive_radius.h), one factor per pass as the schedule extends.
  if (x_of_pass_.empty()) x_of_pass_.push_back(1.0);
  while (x_of_pass_.size() <= pass) {
    const double i = double(x_of_pass_.size());
    x_of_pass_.push_back(x_of_pass_.back() * (i + alpha_) / (i + 1.0));
  }
  const double x = x_of_pass_[pass];
  // The task's mean luminance per block it touches. A task is a tile (or the whole image), so it
  // touches few blocks: a short list, found by the last block seen first.
  struct Part {
    size_t block;
    double lum = 0, n = 0;
  };
  std::vector<Part> parts;
  const uint32_t side = kBiasBlockSide;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const uint32_t p = pixels[i];
    const size_t b = size_t(p / uint32_t(width_) / side) * size_t(blocks_x_) + (p % uint32_t(width_)) / side;
    if (parts.empty() || parts.back().block != b) {
      auto it = std::find_if(parts.begin(), parts.end(), [&](const Part& q) { return q.block == b; });
      if (it == parts.end()) {
        parts.push_back(Part{b});
      } else {
        std::iter_swap(it, parts.end() - 1);
      }
    }
    const Rgb c(rgb_sums[3 * i], rgb_sums[3 * i + 1], rgb_sums[3 * i + 2]);
    const double m = std::clamp(double(c.Luminance()) / samples, 0.0, kDisplayWhite);
    parts.back().lum += m;
    parts.back().n += 1;
    passes_[p] += 1;
    sum_[p] += m;
    sum2_[p] += m * m;
  }
  for (const Part& part : parts) {
    Fit& f = fits_[part.block];
    const double m = part.lum / part.n, w = part.n;
    f.contributions += 1;
    f.w += w;
    f.wx += w * x;
    f.wxx += w * x * x;
    f.wm += w * m;
    f.wmm += w * m * m;
    f.wxm += w * x * m;
  }
}

std::vector<double> ProgressiveBias::BlockBias2() const {
  std::vector<double> out(fits_.size(), std::numeric_limits<double>::quiet_NaN());
  for (size_t b = 0; b < fits_.size(); ++b) {
    const Fit& f = fits_[b];
    if (f.contributions < kMinPassesForBias) continue;
    const double sxx = f.wxx - f.wx * f.wx / f.w;  // Σ w (x − x̄)²
    if (!(sxx > 1e-12 * f.wxx)) continue;          // one radius only: no slope to fit
    const double sxm = f.wxm - f.wx * f.wm / f.w;
    const double smm = f.wmm - f.wm * f.wm / f.w;
    const double slope = sxm / sxx;
    const double residual = std::max(0.0, smm - slope * sxm);  // Σ w (m − fit)²
    const double slope_var = residual / (f.contributions - 2.0) / sxx;
    const double mean_x = f.wx / f.w;
    out[b] = mean_x * mean_x * (slope * slope - slope_var);
  }
  return out;
}

double ProgressiveBias::BiasRms() const {
  const std::vector<double> bias2 = BlockBias2();
  double sum = 0, weight = 0;
  for (size_t b = 0; b < bias2.size(); ++b) {
    if (std::isnan(bias2[b])) continue;
    // Weighted by the block's pixels (edge blocks are smaller); the noise-corrected estimates are
    // averaged before clamping, so their noise cancels rather than adds.
    const double pixels = fits_[b].w / fits_[b].contributions;
    sum += pixels * bias2[b];
    weight += pixels;
  }
  if (weight <= 0) return -1.0;
  return std::sqrt(std::max(0.0, sum / weight));
}

double ProgressiveBias::NoiseRms() const {
  double sum_var = 0;
  size_t covered = 0;
  for (size_t p = 0; p < passes_.size(); ++p) {
    const double c = passes_[p];
    if (c < 2) continue;
    const double mean = sum_[p] / c;
    sum_var += std::max(0.0, sum2_[p] / c - mean * mean) / (c - 1.0);  // the sample variance / c
    ++covered;
  }
  return covered ? std::sqrt(sum_var / double(covered)) : -1.0;
}

double ProgressiveBias::ErrorRms() const {
  const double noise = NoiseRms(), bias = BiasRms();
  if (noise < 0 || bias < 0) return -1.0;
  return std::sqrt(noise * noise + bias * bias);
}

bool ProgressiveBias::operator==(const ProgressiveBias& o) const {
  return alpha_ == o.alpha_ && width_ == o.width_ && height_ == o.height_ && fits_ == o.fits_ &&
         passes_ == o.passes_ && sum_ == o.sum_ && sum2_ == o.sum2_;
}

void ProgressiveBias::SerializeTo(ByteWriter& w) const {
  w.Put<double>(alpha_);
  w.Put<uint64_t>(fits_.size());
  for (const Fit& f : fits_)
    for (double v : {f.contributions, f.w, f.wx, f.wxx, f.wm, f.wmm, f.wxm}) w.Put<double>(v);
  w.PutArray<uint32_t>(passes_);
  w.PutArray<double>(sum_);
  w.PutArray<double>(sum2_);
}

ProgressiveBias ProgressiveBias::DeserializeFrom(ByteReader& r, int width, int height) {
  const double alpha = r.Get<double>();
  if (!(alpha > 0.0 && alpha < 1.0)) r.Fail("progressive bias: alpha outside (0, 1)");
  ProgressiveBias b(alpha, width, height);
  const uint64_t n = r.Get<uint64_t>();
  if (n != b.fits_.size()) r.Fail("progressive bias: block count does not match the image");
  if (r.remaining() < n * 7 * sizeof(double)) r.Fail("truncated");
  for (Fit& f : b.fits_) {
    f.contributions = r.Get<double>();
    f.w = r.Get<double>();
    f.wx = r.Get<double>();
    f.wxx = r.Get<double>();
    f.wm = r.Get<double>();
    f.wmm = r.Get<double>();
    f.wxm = r.Get<double>();
  }
  const size_t pixels = b.passes_.size();
  if (r.remaining() < pixels * (sizeof(uint32_t) + 2 * sizeof(double))) r.Fail("truncated");
  r.GetArray<uint32_t>(b.passes_);
  r.GetArray<double>(b.sum_);
  r.GetArray<double>(b.sum2_);
  return b;
}

}  // namespace pf
