#include "common/plan/accumulator.h"

#include <cmath>
#include <cstring>

#include "common/core/error.h"

namespace pf {
namespace {

constexpr double kFixedScale = 4294967296.0;  // 2^32
constexpr double kMaxTaskSum = 1073741824.0;  // 2^30
constexpr char kMagic[8] = {'P', 'F', 'A', 'C', 'C', 'U', 'M', '1'};

template <typename T>
void Put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <typename T>
void PutVector(std::string& out, const std::vector<T>& v) {
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}
template <typename T>
T Get(std::string_view& in) {
  if (in.size() < sizeof(T)) throw InputError("accumulator checkpoint: truncated");
  T v;
  std::memcpy(&v, in.data(), sizeof(T));
  in.remove_prefix(sizeof(T));
  return v;
}
template <typename T>
void GetVector(std::string_view& in, std::vector<T>& v, size_t n) {
  if (in.size() < n * sizeof(T)) throw InputError("accumulator checkpoint: truncated");
  v.resize(n);
  std::memcpy(v.data(), in.data(), n * sizeof(T));
  in.remove_prefix(n * sizeof(T));
}

}  // namespace

Accumulator::Accumulator(int width, int height)
    : width_(width),
      height_(height),
      sums_(size_t(width) * height * 3, 0),
      samples_(size_t(width) * height, 0),
      maps_(size_t(width) * height, 0),
      lum_sum_(size_t(width) * height, 0.0),
      lum_sum2_(size_t(width) * height, 0.0) {}

std::string Accumulator::ValidateTaskResult(std::span<const float> rgb_sums, uint64_t expected_pixels,
                                            uint32_t samples) {
  if (samples == 0) return "result: zero samples";
  if (rgb_sums.size() != expected_pixels * 3)
    return "result: rgb_sums has " + std::to_string(rgb_sums.size()) + " values, expected " +
           std::to_string(expected_pixels * 3) + " (3 per pixel of the subset)";
  for (size_t i = 0; i < rgb_sums.size(); ++i) {
    if (!std::isfinite(rgb_sums[i])) return "result: rgb_sums[" + std::to_string(i) + "] is not finite";
    if (std::fabs(double(rgb_sums[i])) > kMaxTaskSum)
      return "result: rgb_sums[" + std::to_string(i) + "] exceeds the accumulator range (2^30)";
  }
  return "";
}

void Accumulator::Add(std::span<const uint32_t> pixels, std::span<const float> rgb_sums, uint32_t samples) {
  const std::string problem = ValidateTaskResult(rgb_sums, pixels.size(), samples);
  if (!problem.empty()) throw InputError(problem);
  const size_t n = size_t(width_) * height_;
  for (uint32_t p : pixels)
    if (p >= n) throw InputError("result: pixel index " + std::to_string(p) + " outside the image");
  for (size_t i = 0; i < pixels.size(); ++i) {
    const uint32_t p = pixels[i];
    const Rgb c(rgb_sums[3 * i], rgb_sums[3 * i + 1], rgb_sums[3 * i + 2]);
    for (int k = 0; k < 3; ++k) sums_[3 * size_t(p) + k] += int64_t(std::llround(double(c[k]) * kFixedScale));
    samples_[p] += samples;
    maps_[p] += 1;
    const double m = double(c.Luminance()) / samples;
    lum_sum_[p] += samples * m;
    lum_sum2_[p] += samples * m * m;
  }
  samples_merged_ += uint64_t(pixels.size()) * samples;
  ++tasks_merged_;
}

Image Accumulator::Resolve() const {
  Image img(width_, height_);
  for (size_t p = 0; p < img.size(); ++p) {
    if (samples_[p] == 0) continue;
    const double inv = 1.0 / (kFixedScale * samples_[p]);
    img[p] = Rgb(float(double(sums_[3 * p]) * inv), float(double(sums_[3 * p + 1]) * inv),
                 float(double(sums_[3 * p + 2]) * inv));
  }
  return img;
}

double Accumulator::EstimatedNoiseRms() const {
  double sum_var = 0;
  size_t covered = 0;
  for (size_t p = 0; p < samples_.size(); ++p) {
    const uint32_t c = maps_[p];
    if (c < 2) continue;
    const double w = samples_[p];
    const double mean = lum_sum_[p] / w;
    const double var_map = std::max(0.0, lum_sum2_[p] / w - mean * mean) * c / (c - 1.0);
    sum_var += var_map / c;  // variance of the mean over c independent maps
    ++covered;
  }
  return covered ? std::sqrt(sum_var / covered) : -1.0;
}

std::string Accumulator::Serialize() const {
  std::string out;
  out.append(kMagic, sizeof(kMagic));
  Put(out, int32_t(width_));
  Put(out, int32_t(height_));
  Put(out, samples_merged_);
  Put(out, tasks_merged_);
  PutVector(out, sums_);
  PutVector(out, samples_);
  PutVector(out, maps_);
  PutVector(out, lum_sum_);
  PutVector(out, lum_sum2_);
  return out;
}

Accumulator Accumulator::Deserialize(std::string_view in) {
  if (in.size() < sizeof(kMagic) || std::memcmp(in.data(), kMagic, sizeof(kMagic)) != 0)
    throw InputError("accumulator checkpoint: bad magic");
  in.remove_prefix(sizeof(kMagic));
  const int32_t w = Get<int32_t>(in), h = Get<int32_t>(in);
  if (w <= 0 || h <= 0 || int64_t(w) * h > (int64_t(1) << 28)) throw InputError("accumulator checkpoint: bad size");
  Accumulator a;
  a.width_ = w;
  a.height_ = h;
  a.samples_merged_ = Get<uint64_t>(in);
  a.tasks_merged_ = Get<uint64_t>(in);
  const size_t n = size_t(w) * h;
  GetVector(in, a.sums_, 3 * n);
  GetVector(in, a.samples_, n);
  GetVector(in, a.maps_, n);
  GetVector(in, a.lum_sum_, n);
  GetVector(in, a.lum_sum2_, n);
  if (!in.empty()) throw InputError("accumulator checkpoint: trailing bytes");
  return a;
}

}  // namespace pf
