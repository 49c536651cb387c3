#include "common/photon/photon.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pf {

DirectionBytes EncodeDirection(const Vec3& direction) {
  // Double precision: acos is ill-conditioned near the poles, and a float acos would add
  // error on top of the quantisation bound documented in photon.h.
  const double x = direction.x, y = direction.y, z = direction.z;
  const double length = std::sqrt(x * x + y * y + z * z);
  if (!(length > 0.0) || !std::isfinite(length)) return {};  // +z by convention
  const double cos_theta = std::clamp(z / length, -1.0, 1.0);
  // Wald 1999, §2.2: theta = 255·acos(ω.z)/π, phi = 256·atan2(ω.y, ω.x)/2π (rounded here).
  const long theta = std::lround(std::acos(cos_theta) * (255.0 / std::numbers::pi));
  const long phi = std::lround(std::atan2(y, x) * (256.0 / (2.0 * std::numbers::pi)));
  DirectionBytes d;
  d.theta = uint8_t(std::clamp(theta, 0L, 255L));
  d.phi = uint8_t(phi & 255);  // two's complement: −1 → 255, 128 (φ = π) → 128
  return d;
}

RgbeBytes EncodeRgbe(const Rgb& power) {
  // Sanitise: NaN and negatives → 0, +Inf → FLT_MAX (then clamped below). Double precision
  // makes c · 2^(8−e) exact, so the only error is the final rounding.
  double c[3];
  for (int i = 0; i < 3; ++i) {
    const double v = power[i];
    c[i] = v > 0.0 ? std::min(v, double(std::numeric_limits<float>::max())) : 0.0;
  }
  double m = std::max(c[0], std::max(c[1], c[2]));
  if (m <= 0.0) return {0, 0, 0, 0};

  // Clamp huge powers to the largest representable one, keeping the chromaticity.
  constexpr double kMax = 255.0 * 0x1p119;
  if (m >= 255.5 * 0x1p119) {
    for (double& v : c) v = (v == m) ? kMax : v / m * kMax;
    m = kMax;
  }

  int e = 0;
  std::frexp(m, &e);      // m = f · 2^e, f ∈ [0.5, 1)
  e = std::max(e, -127);  // gradual underflow: E = e + 128 ≥ 1 (0 means black)
  long mant[3];
  for (int pass = 0; pass < 2; ++pass) {
    const double scale = std::ldexp(1.0, 8 - e);
    for (int i = 0; i < 3; ++i) mant[i] = std::lround(c[i] * scale);
    if (std::max(mant[0], std::max(mant[1], mant[2])) <= 255) break;
    ++e;  // rounding carried into the next binade (cannot pass 127: m < 255.5 · 2^119)
  }
  if (mant[0] == 0 && mant[1] == 0 && mant[2] == 0) return {0, 0, 0, 0};
  return {uint8_t(mant[0]), uint8_t(mant[1]), uint8_t(mant[2]), uint8_t(e + 128)};
}

}  // namespace pf
