#pragma once
// The merge arithmetic (docs/design.md, §1 Merge): per pixel Σ w·c / Σ w, where a
// task contributes the sum of its samples with weight = its sample count.
//
// Determinism (docs/design.md, G1): the sums are kept in 64-bit fixed point (2^-32 units), so
// addition is exact and associative, and the merged image is bit-identical whatever order the
// tasks complete in, however many workers ran them. Range: a pixel's channel sum must stay
// within 2^31 (checked per task: ValidateTaskResult rejects a task whose sums exceed 2^30).
//
// Noise estimate (docs/design.md, §1 Error estimate): samples of a pixel from different maps are
// independent, so the spread of the per-map pixel means (luminance) estimates the pixel's
// variance; EstimatedNoiseRms is the RMS over pixels covered by ≥ 2 maps of the standard error
// of their mean. Kept in double: it only steers progress and the stop rule, never the image.
// For the progressive plan the accumulator also estimates the bias the noise estimate cannot see
// (progressive_bias.h), from the passes' radii: the schedule's α is the job's progressive-alpha.

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/image/image.h"
#include "common/plan/error_estimates.h"
#include "common/plan/hierarchical.h"
#include "common/plan/progressive_bias.h"
#include "common/plan/task_plan.h"

namespace pf {

// What checking a task result found (Accumulator::ValidateTaskResult).
struct ResultCheck {
  enum class Verdict {
    kOk,
    kInvalid,      // wrong size, NaN/Inf, negative, outside the accumulator's range: never merged
    kImplausible,  // above the job's bound: merged only if another worker reproduces it exactly
  };
  Verdict verdict = Verdict::kOk;
  std::string reason;  // "" when kOk
  bool ok() const { return verdict == Verdict::kOk; }
};

class Accumulator {
 public:
  Accumulator() = default;
  Accumulator(int width, int height);
  // For a job's plan: the hierarchical plan (§4.5) assembles interpolation and details
  // (HierarchicalAssembly); every other plan is the weighted mean above. progressive_alpha is the
  // job's progressive-alpha setting (the radius schedule): read by the progressive plan only.
  Accumulator(const PlanSpec& plan, int width, int height, double progressive_alpha);

  // Checks a task result before anything is merged: 3 values per pixel, each finite and ≥ 0
  // (every estimator of the renderer is a sum of products of non-negative terms: emission,
  // BSDF values, photon powers, MIS and roulette weights; the scene loaders reject negative
  // colours), within the fixed-point range (2^30), and — kImplausible — at most
  // samples × max_sample_radiance (the per-job bound, docs/security.md "Results").
  static ResultCheck ValidateTaskResult(std::span<const float> rgb_sums, uint64_t expected_pixels,
                                        uint32_t samples,
                                        double max_sample_radiance = std::numeric_limits<double>::infinity());

  // Merges one task: rgb_sums holds 3 floats per pixel of `pixels` (same order), each the sum
  // over `samples` samples. Validates first (ValidateTaskResult); invalid input throws InputError.
  void Add(std::span<const uint32_t> pixels, std::span<const float> rgb_sums, uint32_t samples);
  // Add for a result that already passed ValidateTaskResult for these pixels and samples (the
  // coordinator checks each result once, where it arrives: server/assembly/result_merger.h).
  // Pixel indices outside the image still throw InputError.
  void AddValidated(std::span<const uint32_t> pixels, std::span<const float> rgb_sums, uint32_t samples);
  // The same for the result of `task` (the hierarchical assembly needs to know which task).
  void AddValidated(const TaskSpec& task, std::span<const uint32_t> pixels, std::span<const float> rgb_sums,
                    uint32_t samples);
  // The hierarchical assembly, if the plan is hierarchical.
  const HierarchicalAssembly* hierarchy() const { return hierarchy_ ? &*hierarchy_ : nullptr; }

  Image Resolve() const;             // Σ/n per pixel; black where n = 0
  double EstimatedNoiseRms() const;  // < 0 while no pixel has two maps, and for the hierarchical plan
  // EstimatedNoiseRms and, for the progressive plan, its bias indicator and error estimate
  // (ProgressiveBias: BiasRms, ErrorRms — display-clamped; the number --target-error compares).
  // bias/error < 0 for other plans, before kMinPassesForBias passes, and for a checkpoint written
  // before the indicator existed.
  ErrorEstimates Estimates() const;
  const ProgressiveBias* progressive_bias() const { return bias_ ? &*bias_ : nullptr; }
  uint64_t samples_merged() const { return samples_merged_; }
  uint64_t tasks_merged() const { return tasks_merged_; }
  int width() const { return width_; }
  int height() const { return height_; }

  // Checkpoint format: little-endian binary with a magic, a version and the sizes.
  std::string Serialize() const;
  // Throws InputError if malformed; a hierarchical checkpoint needs its job's plan.
  static Accumulator Deserialize(std::string_view bytes, const PlanSpec* plan = nullptr);

  bool operator==(const Accumulator& o) const = default;

 private:
  int width_ = 0, height_ = 0;
  std::vector<int64_t> sums_;      // 3 per pixel, fixed point 2^-32
  std::vector<uint32_t> samples_;  // per pixel
  std::vector<uint32_t> maps_;     // contributions per pixel
  std::vector<double> lum_sum_;    // Σ n·m (m = per-map mean luminance)
  std::vector<double> lum_sum2_;   // Σ n·m²
  uint64_t samples_merged_ = 0;
  uint64_t tasks_merged_ = 0;
  std::optional<HierarchicalAssembly> hierarchy_;
  std::optional<ProgressiveBias> bias_;  // the progressive plan's
};

}  // namespace pf
