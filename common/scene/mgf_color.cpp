// MGF colour conversions (mgf_color.h); the spec is mgfdoc.tr (§3 c/cxy/cspec/cct/cmix, §6.1.1).

#include "common/scene/mgf_color.h"

#include <algorithm>
#include <cmath>

namespace pf::mgf {
namespace {

// CIE 1931 2° standard observer colour-matching functions x̄ ȳ z̄, 380..780 nm every 10 nm.
// Coarse, but the spectra in MGF libraries are themselves 10-20 nm samples; the table sums agree
// with the 1 nm tables to 1e-4 and equal-energy white comes out at (0.3334, 0.3334).
constexpr double kCmfFirst = 380.0;
constexpr double kCmfLast = 780.0;
constexpr double kCmfStep = 10.0;
constexpr int kCmfCount = 41;
constexpr double kCmf[kCmfCount][3] = {
    {0.001368, 0.000039, 0.006450}, {0.004243, 0.000120, 0.020050}, {0.014310, 0.000396, 0.067850},
    {0.043510, 0.001210, 0.207400}, {0.134380, 0.004000, 0.645600}, {0.283900, 0.011600, 1.385600},
    {0.348280, 0.023000, 1.747060}, {0.336200, 0.038000, 1.772110}, {0.290800, 0.060000, 1.669200},
    {0.195360, 0.090980, 1.287640}, {0.095640, 0.139020, 0.812950}, {0.032010, 0.208020, 0.465180},
    {0.004900, 0.323000, 0.272000}, {0.009300, 0.503000, 0.158200}, {0.063270, 0.710000, 0.078250},
    {0.165500, 0.862000, 0.042160}, {0.290400, 0.954000, 0.020300}, {0.433450, 0.994950, 0.008750},
    {0.594500, 0.995000, 0.003900}, {0.762100, 0.952000, 0.002100}, {0.916300, 0.870000, 0.001650},
    {1.026300, 0.757000, 0.001100}, {1.062200, 0.631000, 0.000800}, {1.002600, 0.503000, 0.000340},
    {0.854450, 0.381000, 0.000190}, {0.642400, 0.265000, 0.000050}, {0.447900, 0.175000, 0.000020},
    {0.283500, 0.107000, 0.000000}, {0.164900, 0.061000, 0.000000}, {0.087400, 0.032000, 0.000000},
    {0.046770, 0.017000, 0.000000}, {0.022700, 0.008210, 0.000000}, {0.011359, 0.004102, 0.000000},
    {0.005790, 0.002091, 0.000000}, {0.002899, 0.001047, 0.000000}, {0.001440, 0.000520, 0.000000},
    {0.000690, 0.000249, 0.000000}, {0.000332, 0.000120, 0.000000}, {0.000166, 0.000060, 0.000000},
    {0.000083, 0.000030, 0.000000}, {0.000042, 0.000015, 0.000000},
};

Vec3d CmfAt(double lambda) {
  if (!(lambda >= kCmfFirst && lambda <= kCmfLast)) return {};
  const double t = (lambda - kCmfFirst) / kCmfStep;
  const int i = std::min(static_cast<int>(t), kCmfCount - 2);
  const double f = t - i;
  return {kCmf[i][0] + f * (kCmf[i + 1][0] - kCmf[i][0]), kCmf[i][1] + f * (kCmf[i + 1][1] - kCmf[i][1]),
          kCmf[i][2] + f * (kCmf[i + 1][2] - kCmf[i][2])};
}

// Integrates a spectral function against the CMFs in 1 nm steps (the CMFs interpolated from
// the 10 nm table), so that narrow spectra between two table entries still register.
template <typename SpectrumFn>
Vec3d IntegrateXyz(SpectrumFn&& spectrum) {
  Vec3d xyz;
  for (int l = static_cast<int>(kCmfFirst); l <= static_cast<int>(kCmfLast); ++l) {
    const double v = spectrum(static_cast<double>(l));
    if (v != 0.0) xyz += CmfAt(l) * v;
  }
  return xyz;
}

// The XYZ -> RGB matrix of §6.1.1 ("Converting between RGB and CIE Colors"): the spec's code
// for its nominal CRT primaries and equal-energy white, written out as its closed form.
struct Matrix3 {
  double m[3][3];
};
constexpr Matrix3 MakeXyzToRgb() {
  constexpr double xr = 0.640, yr = 0.330;  // nominal CRT primaries (the non-NTSC branch)
  constexpr double xg = 0.290, yg = 0.600;
  constexpr double xb = 0.150, yb = 0.060;
  constexpr double xw = 1.0 / 3.0, yw = 1.0 / 3.0;  // "monitor white point"
  constexpr double c_r = (xw * (yg - yb) - yw * (xg - xb) + xg * yb - xb * yg) / yw;
  constexpr double c_g = (xw * (yb - yr) - yw * (xb - xr) - xr * yb + xb * yr) / yw;
  constexpr double c_b = (xw * (yr - yg) - yw * (xr - xg) + xr * yg - xg * yr) / yw;
  return Matrix3{
      {{(yg - yb - xb * yg + yb * xg) / c_r, (xb - xg - xb * yg + xg * yb) / c_r, (xg * yb - xb * yg) / c_r},
       {(yb - yr - yb * xr + yr * xb) / c_g, (xr - xb - xr * yb + xb * yr) / c_g, (xb * yr - xr * yb) / c_g},
       {(yr - yg - yr * xg + yg * xr) / c_b, (xg - xr - xg * yr + xr * yg) / c_b,
        (xr * yg - xg * yr) / c_b}}};
}
constexpr Matrix3 kXyzToRgb = MakeXyzToRgb();

}  // namespace

bool XyzToChroma(const Vec3d& xyz, Chroma* c) {
  const double sum = xyz.x + xyz.y + xyz.z;
  if (!(xyz.y > 0.0) || !(sum > 0.0) || !std::isfinite(sum)) return false;
  c->x = xyz.x / sum;
  c->y = xyz.y / sum;
  return std::isfinite(c->x) && std::isfinite(c->y) && c->y >= kMinChromaY;
}

bool BlackbodyToChroma(double t, Chroma* c) {
  // Planck's law; only relative values matter (the colour is normalised).
  constexpr double kC2 = 1.4387769e-2;  // second radiation constant, m·K
  const Vec3d xyz = IntegrateXyz([t](double nm) {
    const double l = nm * 1e-9;
    const double e = std::expm1(kC2 / (l * t));
    return std::isfinite(e) && e > 0.0 ? 1.0 / (std::pow(l * 1e6, 5.0) * e) : 0.0;
  });
  return XyzToChroma(xyz, c);
}

Rgb ChromaRgb(const Chroma& c) {
  return CieToRgb(c.x, c.y, 1.0);
}

Rgb CieToRgb(double x, double y, double Y) {
  if (!(y > 0.0)) return Rgb();
  const double xyz[3] = {x / y * Y, Y, (1.0 - x - y) / y * Y};
  Rgb out;
  for (int i = 0; i < 3; ++i) {
    const double v = kXyzToRgb.m[i][0] * xyz[0] + kXyzToRgb.m[i][1] * xyz[1] + kXyzToRgb.m[i][2] * xyz[2];
    // "watch for negative values" (§6.1.1); the upper clamp only keeps the float cast defined.
    out[i] = v > 0.0 ? static_cast<float>(std::min(v, 1e30)) : 0.0f;
  }
  return out;
}

bool SpectrumToXy(double lambda_min, double lambda_max, const double* values, size_t count, double* x,
                  double* y) {
  if (count < 2 || !(lambda_min < lambda_max)) return false;
  const double step = (lambda_max - lambda_min) / static_cast<double>(count - 1);
  if (!(step > 0.0) || !std::isfinite(step)) return false;
  // §3 cspec: evenly spaced samples, linearly interpolated, zero outside [l_min, l_max].
  const Vec3d xyz = IntegrateXyz([&](double l) {
    if (l < lambda_min || l > lambda_max) return 0.0;
    const double t = (l - lambda_min) / step;
    const size_t i = std::min(static_cast<size_t>(t), count - 2);
    const double f = t - static_cast<double>(i);
    return values[i] + f * (values[i + 1] - values[i]);
  });
  Chroma c;
  if (!XyzToChroma(xyz, &c)) return false;
  *x = c.x;
  *y = c.y;
  return true;
}

}  // namespace pf::mgf
