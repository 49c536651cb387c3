#include "common/plan/accumulator.h"

#include <cmath>
#include <cstdio>
#include <cstring>

#include "common/core/byte_codec.h"
#include "common/core/error.h"

namespace pf {
namespace {

constexpr double kFixedScale = 4294967296.0;  // 2^32
constexpr double kMaxTaskSum = 1073741824.0;  // 2^30
constexpr char kMagic[8] = {'P', 'F', 'A', 'C', 'C', 'U', 'M', '1'};
constexpr char kHierarchicalMagic[8] = {'P', 'F', 'A', 'C', 'C', 'H', 'L', '1'};
// The weighted-mean body followed by the progressive plan's bias fits (progressive_bias.h).
constexpr char kProgressiveMagic[8] = {'P', 'F', 'A', 'C', 'C', 'P', 'B', '1'};

}  // namespace

Accumulator::Accumulator(int width, int height)
    : width_(width),
      height_(height),
      sums_(size_t(width) * height * 3, 0),
      samples_(size_t(width) * height, 0),
      maps_(size_t(width) * height, 0),
      lum_sum_(size_t(width) * height, 0.0),
      lum_sum2_(size_t(width) * height, 0.0) {}

Accumulator::Accumulator(const PlanSpec& plan, int width, int height, double progressive_alpha) {
  if (plan.kind != PlanKind::kHierarchical) {
    *this = Accumulator(width, height);
    if (plan.kind == PlanKind::kProgressive) bias_.emplace(progressive_alpha, width, height);
    return;
  }
  width_ = width;
  height_ = height;
  hierarchy_.emplace(plan, width, height);
}

void Accumulator::AddValidated(const TaskSpec& task, std::span<const uint32_t> pixels,
                               std::span<const float> rgb_sums, uint32_t samples) {
  if (!hierarchy_) {
    AddValidated(pixels, rgb_sums, samples);
    if (bias_ && task.progressive) bias_->Add(task.map_index, pixels, rgb_sums, samples);
    return;
  }
  if (hierarchy_->Add(task, pixels, rgb_sums, samples)) {
    samples_merged_ += uint64_t(pixels.size()) * samples;
    ++tasks_merged_;
  }
}

ResultCheck Accumulator::ValidateTaskResult(std::span<const float> rgb_sums, uint64_t expected_pixels,
                                            uint32_t samples, double max_sample_radiance) {
  using V = ResultCheck::Verdict;
  if (samples == 0) return {V::kInvalid, "result: zero samples"};
  if (rgb_sums.size() != expected_pixels * 3)
    return {V::kInvalid, "result: rgb_sums has " + std::to_string(rgb_sums.size()) + " values, expected " +
                             std::to_string(expected_pixels * 3) + " (3 per pixel of the subset)"};
  // The bound in float arithmetic would round; in double it is exact enough for any samples.
  const double bound = double(samples) * max_sample_radiance;
  size_t first_implausible = rgb_sums.size();
  for (size_t i = 0; i < rgb_sums.size(); ++i) {
    const float v = rgb_sums[i];
    if (!std::isfinite(v)) return {V::kInvalid, "result: rgb_sums[" + std::to_string(i) + "] is not finite"};
    if (v < 0.0f)  // -0.0 passes: it is zero
      return {V::kInvalid, "result: rgb_sums[" + std::to_string(i) + "] = " + std::to_string(v) +
                               " is negative (radiance is never negative)"};
    if (double(v) > kMaxTaskSum)
      return {V::kInvalid,
              "result: rgb_sums[" + std::to_string(i) + "] exceeds the accumulator range (2^30)"};
    if (double(v) > bound && first_implausible == rgb_sums.size()) first_implausible = i;
  }
  if (first_implausible < rgb_sums.size()) {
    char text[160];
    std::snprintf(
        text, sizeof(text), "result: rgb_sums[%zu] = %.6g exceeds the job's bound %.6g (%u samples x %.6g)",
        first_implausible, double(rgb_sums[first_implausible]), bound, samples, max_sample_radiance);
    return {V::kImplausible, text};
  }
  return {};
}

void Accumulator::Add(std::span<const uint32_t> pixels, std::span<const float> rgb_sums, uint32_t samples) {
  const ResultCheck check = ValidateTaskResult(rgb_sums, pixels.size(), samples);
  if (!check.ok()) throw InputError(check.reason);
  AddValidated(pixels, rgb_sums, samples);
}

void Accumulator::AddValidated(std::span<const uint32_t> pixels, std::span<const float> rgb_sums,
                               uint32_t samples) {
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
  if (hierarchy_) return hierarchy_->Resolve();
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
  if (hierarchy_) return -1;
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

ErrorEstimates Accumulator::Estimates() const {
  ErrorEstimates e;
  e.noise = EstimatedNoiseRms();
  if (bias_) {
    e.display_noise = bias_->NoiseRms();
    e.bias = bias_->BiasRms();
    e.error = bias_->ErrorRms();
  }
  return e;
}

std::string Accumulator::Serialize() const {
  std::string out;
  if (!hierarchy_) out.reserve(sizeof(kMagic) + 24 + sums_.size() * 8 + samples_.size() * 24);
  ByteWriter w(out);
  // One header for both layouts; the magic says which body follows.
  w.PutBytes(hierarchy_ ? std::string_view(kHierarchicalMagic, sizeof(kHierarchicalMagic))
             : bias_    ? std::string_view(kProgressiveMagic, sizeof(kProgressiveMagic))
                        : std::string_view(kMagic, sizeof(kMagic)));
  w.Put<int32_t>(width_);
  w.Put<int32_t>(height_);
  w.Put<uint64_t>(samples_merged_);
  w.Put<uint64_t>(tasks_merged_);
  if (hierarchy_) {
    hierarchy_->SerializeTo(out);
    return out;
  }
  w.PutArray<int64_t>(sums_);
  w.PutArray<uint32_t>(samples_);
  w.PutArray<uint32_t>(maps_);
  w.PutArray<double>(lum_sum_);
  w.PutArray<double>(lum_sum2_);
  if (bias_) bias_->SerializeTo(w);
  return out;
}

Accumulator Accumulator::Deserialize(std::string_view in, const PlanSpec* plan) {
  if (in.size() >= sizeof(kHierarchicalMagic) &&
      std::memcmp(in.data(), kHierarchicalMagic, sizeof(kHierarchicalMagic)) == 0) {
    if (!plan || plan->kind != PlanKind::kHierarchical)
      throw InputError("accumulator checkpoint: hierarchical, but the job's plan is not");
    ByteReader r(in.substr(sizeof(kHierarchicalMagic)), "accumulator checkpoint");
    const int32_t w = r.Get<int32_t>(), h = r.Get<int32_t>();
    if (w <= 0 || h <= 0 || int64_t(w) * h > (int64_t(1) << 28))
      throw InputError("accumulator checkpoint: bad size");
    Accumulator a(*plan, w, h, /*progressive_alpha, unused by the hierarchical plan=*/0.5);
    a.samples_merged_ = r.Get<uint64_t>();
    a.tasks_merged_ = r.Get<uint64_t>();
    a.hierarchy_->DeserializeFrom(r);
    if (a.hierarchy_->tasks_merged() != a.tasks_merged_)
      throw InputError("accumulator checkpoint: task counts disagree");
    return a;
  }
  if (plan && plan->kind == PlanKind::kHierarchical)
    throw InputError("accumulator checkpoint: not hierarchical, but the job's plan is");
  const bool progressive = in.size() >= sizeof(kProgressiveMagic) &&
                           std::memcmp(in.data(), kProgressiveMagic, sizeof(kProgressiveMagic)) == 0;
  if (!progressive && (in.size() < sizeof(kMagic) || std::memcmp(in.data(), kMagic, sizeof(kMagic)) != 0))
    throw InputError("accumulator checkpoint: bad magic");
  // A progressive job's checkpoint from before the bias fits (kMagic) restores without them: its
  // bias stays unknown rather than fitted to the later passes only.
  ByteReader r(in.substr(sizeof(kMagic)), "accumulator checkpoint");
  const int32_t w = r.Get<int32_t>(), h = r.Get<int32_t>();
  if (w <= 0 || h <= 0 || int64_t(w) * h > (int64_t(1) << 28))
    throw InputError("accumulator checkpoint: bad size");
  Accumulator a;
  a.width_ = w;
  a.height_ = h;
  a.samples_merged_ = r.Get<uint64_t>();
  a.tasks_merged_ = r.Get<uint64_t>();
  const size_t n = size_t(w) * h;
  // Sizes are checked before allocating: a corrupt header must not allocate gigabytes.
  constexpr size_t kBytesPerPixel = 3 * sizeof(int64_t) + 2 * sizeof(uint32_t) + 2 * sizeof(double);
  if (r.remaining() < n * kBytesPerPixel || (!progressive && r.remaining() != n * kBytesPerPixel))
    r.Fail(r.remaining() < n * kBytesPerPixel ? "truncated" : "trailing bytes");
  a.sums_.resize(3 * n);
  a.samples_.resize(n);
  a.maps_.resize(n);
  a.lum_sum_.resize(n);
  a.lum_sum2_.resize(n);
  r.GetArray<int64_t>(a.sums_);
  r.GetArray<uint32_t>(a.samples_);
  r.GetArray<uint32_t>(a.maps_);
  r.GetArray<double>(a.lum_sum_);
  r.GetArray<double>(a.lum_sum2_);
  if (progressive) {
    a.bias_ = ProgressiveBias::DeserializeFrom(r, w, h);
    if (r.remaining() != 0) r.Fail("trailing bytes");
  }
  return a;
}

}  // namespace pf
