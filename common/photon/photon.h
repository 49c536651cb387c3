#pragma once
// The compact 18-byte photon of Wald 1999, §2.2 (after Jensen 1996):
//
//   float position[3]   12 bytes, plain floats (doubles would nearly double the memory for
//                       little accuracy, §2.2)
//   uint8 theta, phi     2 bytes, the incoming direction quantised to two angles
//   uint8 rgbe[4]        4 bytes, the power in Ward's shared-exponent RGBE ("real pixels")
//
// There is no spare byte, so the kd-tree's split axis is *not* stored in the photon (the
// thesis's kd-tree uses `level % 3`, which needs no storage). The optional widest-extent
// kd-tree keeps its axes in a 2-bit-per-node side array (see kdtree.h).
//
// Encoding rules and their error bounds (checked by tests/common/photon_test.cpp):
//
// Direction (any non-zero finite vector, normalised first):
//   theta = round(255 · acos(ω.z) / π)            ∈ [0, 255], decoded θ' = theta·π/255
//   phi   = round(256 · atan2(ω.y, ω.x) / 2π) mod 256,       decoded φ' = phi·2π/256
//   We round to nearest (the thesis truncates), which halves the error: |θ−θ'| ≤ π/510 and
//   |φ−φ'| ≤ π/256. The haversine formula, hav(α) = hav(θ−θ') + sinθ·sinθ'·hav(φ−φ') with
//   hav(x) = sin²(x/2) and sinθ·sinθ' ≤ 1, bounds the angle α between ω and the decoded ω':
//   kMaxDirectionErrorRadians = 2·asin(√(sin²(π/1020) + sin²(π/512))) ≈ 0.013731 rad
//   ≈ 0.787° (attained near the equator, where the two errors are orthogonal).
//   Zero, NaN or infinite vectors encode as (0, 0), i.e. +z.
//
// Power (RGBE, Ward 1991), for channels c with maximum m:
//   m = f·2^e, f ∈ [0.5, 1); E = e + 128; mantissa byte M_c = round(c · 2^(8−e)).
//   Decoding is exact in float: c' = M_c · 2^(E−136); E == 0 means black.
//   If rounding carries the largest mantissa to 256, e is incremented and all channels are
//   re-rounded (so M_max ∈ [128, 255] always). For m ≥ 2^-128:
//   * max channel: relative error ≤ 2^-8 (half a step over M ≥ 128)
//   * every channel: absolute error ≤ half a step ≤ 2^-8 · m' (m' = decoded max) and
//     ≤ m / 255.5 (just above 2^-8 · m, only in the carry case)
//   * zero channels stay exactly zero (we round instead of Ward's truncate-and-add-0.5)
//   * tiny: for m < 2^-128 the exponent sticks at E = 1 (gradual underflow, like float
//     denormals): absolute error ≤ 2^-136; m below 2^-136 may encode as black
//   * huge: m ≥ 255.5·2^119 (≈ 1.7e38, includes +Inf) is clamped to the largest
//     representable value 255·2^119 with the chromaticity kept
//   * NaN and negative channels encode as 0 (photon powers are non-negative)
//   Decoding never produces NaN or Inf.

#include <array>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <type_traits>

#include "common/core/math.h"

namespace pf {

// Bound on the angle between a unit direction and its decoded form (see above).
// 2·asin(√(sin²(π/1020) + sin²(π/512))), evaluated (tests recompute it).
inline constexpr double kMaxDirectionErrorRadians = 0.013731153872135988;
// Bound on the relative error of the largest channel of a non-tiny power, and on the error
// of every channel relative to that largest channel.
inline constexpr double kMaxRgbeRelativeError = 1.0 / 256.0;
// The largest power channel RGBE can hold: 255 · 2^119.
inline constexpr float kMaxRgbeValue = 255.0f * 0x1p119f;

struct DirectionBytes {
  uint8_t theta = 0;
  uint8_t phi = 0;
};
using RgbeBytes = std::array<uint8_t, 4>;

DirectionBytes EncodeDirection(const Vec3& direction);
RgbeBytes EncodeRgbe(const Rgb& power);

namespace photon_detail {

// Taylor series, evaluated at compile time so that the lookup tables are constants (no static
// initialisation order to worry about, no guard on the decode path). |x| ≤ π.
constexpr double SinSeries(double x) {
  double term = x, sum = x;
  for (int n = 1; n < 30; ++n) {
    term *= -x * x / double((2 * n) * (2 * n + 1));
    sum += term;
  }
  return sum;
}
constexpr double CosSeries(double x) {
  double term = 1.0, sum = 1.0;
  for (int n = 1; n < 30; ++n) {
    term *= -x * x / double((2 * n - 1) * (2 * n));
    sum += term;
  }
  return sum;
}
constexpr double Wrap(double x) {
  return x > std::numbers::pi ? x - 2.0 * std::numbers::pi : x;
}

struct DirectionTables {
  std::array<float, 256> cos_theta{}, sin_theta{}, cos_phi{}, sin_phi{};
};

// The decode tables of §2.2: cosTheta[i] = cos(iπ/255), cosPhi[i] = cos(2πi/256), ...
constexpr DirectionTables MakeDirectionTables() {
  DirectionTables t;
  for (int i = 0; i < 256; ++i) {
    const double theta = i * std::numbers::pi / 255.0;
    const double phi = Wrap(i * 2.0 * std::numbers::pi / 256.0);
    t.cos_theta[i] = float(CosSeries(theta));
    t.sin_theta[i] = float(SinSeries(theta));
    t.cos_phi[i] = float(CosSeries(phi));
    t.sin_phi[i] = float(SinSeries(phi));
  }
  return t;
}
inline constexpr DirectionTables kDirectionTables = MakeDirectionTables();

// kRgbeScale[E] = 2^(E − 136): the value of one mantissa step for exponent byte E ≥ 1
// (2^-135 is a float denormal, represented exactly). kRgbeScale[0] = 0 makes E == 0 black.
constexpr std::array<float, 256> MakeRgbeScale() {
  std::array<float, 256> s{};
  double v = 1.0;
  for (int i = 0; i < 135; ++i) v *= 0.5;  // 2^-135, exact in double
  for (int e = 1; e < 256; ++e) {
    s[e] = float(v);
    v *= 2.0;
  }
  return s;
}
inline constexpr std::array<float, 256> kRgbeScale = MakeRgbeScale();

}  // namespace photon_detail

inline Vec3 DecodeDirection(DirectionBytes d) {
  const auto& t = photon_detail::kDirectionTables;
  return {t.sin_theta[d.theta] * t.cos_phi[d.phi], t.sin_theta[d.theta] * t.sin_phi[d.phi],
          t.cos_theta[d.theta]};
}

inline Rgb DecodeRgbe(const RgbeBytes& rgbe) {
  const float scale = photon_detail::kRgbeScale[rgbe[3]];
  return {float(rgbe[0]) * scale, float(rgbe[1]) * scale, float(rgbe[2]) * scale};
}

// Wald 1999, §2.2. Packed to exactly 18 bytes: an array of photons is the whole photon map
// (and, for the kd-tree, the whole tree). Members are read by value only; never take a
// pointer or reference to a member (it may be unaligned).
#pragma pack(push, 1)
struct Photon {
  float position[3];
  uint8_t theta;  // see EncodeDirection
  uint8_t phi;
  uint8_t rgbe[4];  // see EncodeRgbe

  static Photon Make(const Vec3& position, const Vec3& direction, const Rgb& power) {
    Photon p;
    p.position[0] = position.x;
    p.position[1] = position.y;
    p.position[2] = position.z;
    const DirectionBytes d = EncodeDirection(direction);
    p.theta = d.theta;
    p.phi = d.phi;
    const RgbeBytes e = EncodeRgbe(power);
    for (int i = 0; i < 4; ++i) p.rgbe[i] = e[i];
    return p;
  }

  Vec3 Position() const { return {position[0], position[1], position[2]}; }
  Vec3 Direction() const { return DecodeDirection({theta, phi}); }
  Rgb Power() const { return DecodeRgbe({rgbe[0], rgbe[1], rgbe[2], rgbe[3]}); }
};
#pragma pack(pop)

static_assert(sizeof(Photon) == 18, "Wald 1999, §2.2: 18 bytes per photon");
static_assert(alignof(Photon) == 1);
static_assert(std::is_trivially_copyable_v<Photon>);
static_assert(std::is_standard_layout_v<Photon>);

// Squared distance from a photon to a point. Every photon map and the brute-force reference
// use this one function, so that they agree bit for bit on every distance (tests compare
// result distance multisets exactly).
inline float DistanceSquared(float px, float py, float pz, const Vec3& x) {
  const float dx = px - x.x;
  const float dy = py - x.y;
  const float dz = pz - x.z;
  return dx * dx + dy * dy + dz * dz;
}
inline float DistanceSquared(const Photon& p, const Vec3& x) {
  return DistanceSquared(p.position[0], p.position[1], p.position[2], x);
}

}  // namespace pf
