#pragma once
// Comparing a rendered image against a reference: error statistics and a false-colour error
// image. Used by convergence tests, benchmarks and the `pf compare` style tools.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/image/image.h"

namespace pf {

// Statistics of `a` against `reference` (b). A pixel is non-finite if any of its channels is
// NaN or infinite; pixels non-finite in either image are counted below and left out of every
// other statistic. Over the remaining `pixels` pixels and their 3 channels (N = 3 * pixels):
//   rmse          = sqrt( sum (a - b)^2 / N )
//   relative_mse  = sum (a - b)^2 / (b^2 + kRelativeMseEpsilon) / N
//   max_abs_error = max |a - b| over pixels and channels, at (max_x, max_y) (first in
//                   row-major order; -1, -1 if no pixel was compared)
//   mean_a/mean_b = sum a / N, sum b / N   (compare these to see a bias in brightness)
// With no pixel compared every statistic is 0. Sums are accumulated in double.
struct ImageDiffStats {
  double rmse = 0;
  // RMSE of the values clamped to [0, 1], the displayable range: the error a viewer sees. Raw
  // RMSE is dominated by the few pixels on the border of a visible light (radiance 10–20 next
  // to 0.5) that a finite number of pixel samples cannot resolve; clamping measures the
  // estimator's noise and bias instead (the thesis's RMS values are on displayed images).
  double rmse_clamped = 0;
  // The same relative to the reference's own display white w: both images clamped to [0, w],
  // RMSE / w, where w = DisplayWhite(reference) (its median luminance shown as middle grey).
  // Scale-free (0.01 = 1 % of white), so a dim scene (CornellBox-Sphere, mean 0.01) is measured
  // like a bright one, and lights count no more than white whatever part of the image they cover.
  double rmse_display = 0;
  double display_white = 0;  // w
  double relative_mse = 0;
  double max_abs_error = 0;
  int max_x = -1, max_y = -1;
  double mean_a = 0, mean_b = 0;
  size_t pixels = 0;  // pixels compared (finite in both images)
  size_t nonfinite_a = 0, nonfinite_b = 0;

  // With an exclusion mask only (see EmitterExclusionMask):
  //   rmse_masked  = RMSE over the compared pixels outside the mask: the noise where the eye
  //                  looks, without the emitters seen directly and the band around them, whose
  //                  partly covered pixels (radiance 17 next to 0.5) dominate the raw RMSE.
  //   rmse_lowfreq = RMSE of the 4x4-pixel block means (per channel) over the blocks lying wholly
  //                  outside the mask: pixel noise averages out 16-fold in a block, what is left
  //                  are errors wider than a block — the photon map's blotches (Wald 1999,
  //                  §3.3.2) and biases.
  //   mean_masked_a, mean_masked_b = the two images' means over the pixels of rmse_masked: the
  //                  brightness away from the emitters, which their partly covered pixels and
  //                  their radiance (10–20 against 0.5) would otherwise dominate.
  bool masked = false;
  double rmse_masked = 0, rmse_lowfreq = 0;
  double mean_masked_a = 0, mean_masked_b = 0;
  size_t pixels_masked = 0;   // pixels in rmse_masked
  size_t blocks_lowfreq = 0;  // 4x4 blocks in rmse_lowfreq
};

// Pixels within this many pixels (Chebyshev distance) of an emitter seen directly are left out
// of rmse_masked; the side of the blocks of rmse_lowfreq.
inline constexpr int kEmitterBandPixels = 2;
inline constexpr int kLowFrequencyBlock = 4;

// 1 for every pixel with emitter coverage > 0 (common/render/emitter_coverage.h) and every pixel
// within `band` pixels of one, else 0. Throws InputError if coverage is not width x height.
std::vector<uint8_t> EmitterExclusionMask(const std::vector<float>& coverage, int width, int height,
                                          int band = kEmitterBandPixels);

// Keeps relative MSE finite where the reference is black; 1e-2 means errors in dark regions
// (|b| << 0.1) are measured roughly as absolute squared errors * 100.
inline constexpr double kRelativeMseEpsilon = 1e-2;

// The radiance a display exposure keyed to the image's median shows as white: median luminance
// (Rec. 709, finite pixels, negatives as 0) / 0.18, Reinhard's key value; the median and not a
// high percentile, because lights may fill more than 1 % of a view (scene8's ceiling panels).
// Falls back to the mean luminance / 0.18 if the median is 0, and to 1 for a black image.
double DisplayWhite(const Image& image);

// Throws InputError naming both sizes if the images differ in size (or the mask, if given, is
// not one byte per pixel). `excluded` (optional): nonzero = left out of the masked metrics.
ImageDiffStats CompareImages(const Image& a, const Image& reference,
                             const std::vector<uint8_t>* excluded = nullptr);

// RMSE over the pixels with selected[i] != 0 that are finite in both images (0 if none).
double RmseOver(const Image& a, const Image& reference, const std::vector<uint8_t>& selected);

// Per pixel error magnitude e = max over channels |a - b|, shown as ErrorColormap(e / scale)
// (clamped to [0, 1]). scale <= 0 means the largest finite-pixel error, so the worst pixel
// maps to the top of the ramp. Pixels non-finite in either image are magenta (1, 0, 1).
// Throws InputError naming both sizes if the images differ in size.
Image FalseColourError(const Image& a, const Image& reference, double scale = 0);

// A viridis-like perceptual ramp from dark purple (t = 0) through blue and green to yellow
// (t = 1), monotonic in lightness. Defined by five sRGB control points of viridis at
// t = 0, 1/4, 1/2, 3/4, 1, interpolated linearly in sRGB and returned as *linear* RGB, so that
// an sRGB preview (png_io.h, exposure 0) shows the intended colours. t is clamped to [0, 1].
Rgb ErrorColormap(double t);

}  // namespace pf
