#pragma once
// The bias indicator of the progressive plan (docs/renderer.md, "Error estimate of the progressive
// plan"). The per-map noise estimate (Accumulator::EstimatedNoiseRms) measures only the spread of
// the passes around their mean; the photon map's bias (Wald 1999, §3.3.2: the blurred, blotchy
// low frequencies) is the same in every pass of one radius and invisible to it. The progressive
// plan's passes differ in one known way, their radius (render/progressive_radius.h), and the bias
// of a density estimate of radius r grows like r² where the illumination is smooth (its leading
// term is r²/8 · ∇²L for a disk kernel). So per image block B the pass means are fitted as
//
//     m_{B,p} = L_B + b_B · x_p + noise,        x_p = r_p² / r_1²,
//
// by least squares over the passes the block has (a line in x), and the bias of the block's
// average over its passes is b_B · x̄_B. Its noise is known from the fit's residuals, so the
// squared bias is estimated without the noise's share: x̄²(b̂² − var b̂). The indicator is the
// RMS over blocks of that estimate, in luminance, like the noise estimate.
//
// Display-referred: every luminance is clamped to [0, kDisplayWhite] first, as pf diff's
// rmse_clamped (image_diff.h). Unclamped, the pixels on the border of a light seen directly
// (radiance 17 next to 0.5, resolved only by more camera samples) would be the whole estimate.
// The noise that goes with it (NoiseRms) is the per-map estimate of the accumulator on the same
// clamped values.
//
// Blocks of kBiasBlockSide² pixels average the per-pixel noise away (by 256 in variance), so the
// fit sees the low-frequency bias; a bias that changes sign within a block (an edge blurred by
// the kernel) partly cancels there and is not seen. Summed in double in arrival order: the value
// steers the stop rule and progress only, never the image.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "common/core/byte_codec.h"

namespace pf {

inline constexpr uint32_t kBiasBlockSide = 16;
// The fit needs degrees of freedom beyond the line for its noise: blocks with fewer passes are
// left out, and the indicator is unknown (< 0) until some block has this many. With 4 (two
// degrees of freedom) the noise correction itself is too noisy to stop a job on.
inline constexpr uint32_t kMinPassesForBias = 8;
// The display's white (image_diff.h: rmse_clamped clamps to [0, 1]).
inline constexpr double kDisplayWhite = 1.0;

class ProgressiveBias {
 public:
  ProgressiveBias() = default;
  ProgressiveBias(double alpha, int width, int height);

  // One task of pass `pass`: rgb_sums holds 3 floats per pixel of `pixels`, each the sum over
  // `samples` samples (the accumulator's input, already validated).
  void Add(uint64_t pass, std::span<const uint32_t> pixels, std::span<const float> rgb_sums,
           uint32_t samples);

  // The RMS over blocks of the estimated bias of each block's mean over its passes; < 0 while no
  // block has kMinPassesForBias passes.
  double BiasRms() const;
  // The RMS over pixels with two passes or more of the standard error of their mean over passes
  // (clamped luminance); < 0 while no pixel has two.
  double NoiseRms() const;
  // √(NoiseRms² + BiasRms²); < 0 while either is unknown.
  double ErrorRms() const;
  // The estimated squared bias of each block (row-major, ⌈width/16⌉ per row); NaN where the
  // block has fewer than kMinPassesForBias passes or one radius only. Unclamped: noise can make it
  // negative.
  std::vector<double> BlockBias2() const;

  void SerializeTo(ByteWriter& w) const;
  static ProgressiveBias DeserializeFrom(ByteReader& r, int width, int height);

  // The fits and the schedule (not the cache of x_p).
  bool operator==(const ProgressiveBias& o) const;

 private:
  // Weighted least-squares sums of one block; a contribution is a task's mean luminance over the
  // block's pixels it holds, weighted by their count.
  struct Fit {
    double contributions = 0, w = 0, wx = 0, wxx = 0, wm = 0, wmm = 0, wxm = 0;
    bool operator==(const Fit& o) const = default;
  };
  double alpha_ = 0;
  int width_ = 0, height_ = 0, blocks_x_ = 0, blocks_y_ = 0;
  std::vector<Fit> fits_;
  // Per pixel: passes, Σ m and Σ m² of its pass means (clamped luminance).
  std::vector<uint32_t> passes_;
  std::vector<double> sum_, sum2_;
  std::vector<double> x_of_pass_;  // x_p, extended on demand (the product is O(p))
};

}  // namespace pf
