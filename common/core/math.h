#pragma once
// Small vector and colour types shared by every part of the renderer.
// Geometry is float (what Embree traces); parsing and transforms may use double (Vec3d).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <type_traits>

namespace pf {

inline constexpr float kPi = std::numbers::pi_v<float>;
inline constexpr float kInvPi = 1.0f / kPi;
inline constexpr float kTwoPi = 2.0f * kPi;

template <typename T>
constexpr T Sq(T v) {
  return v * v;
}

template <typename T>
struct Vec3T {
  T x = 0, y = 0, z = 0;

  constexpr Vec3T() = default;
  constexpr Vec3T(T x_, T y_, T z_) : x(x_), y(y_), z(z_) {}
  constexpr explicit Vec3T(T v) : x(v), y(v), z(v) {}
  // Widening float -> double is exact, so it is implicit (a float point is a world point, e.g. a
  // camera's eye, CameraSpec); every other conversion, narrowing double -> float above all, is
  // explicit.
  template <typename U>
  constexpr explicit(!(std::is_same_v<T, double> && std::is_same_v<U, float>)) Vec3T(const Vec3T<U>& o)
      : x(T(o.x)), y(T(o.y)), z(T(o.z)) {}

  constexpr T operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  constexpr T& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }

  constexpr Vec3T operator+(const Vec3T& o) const { return {x + o.x, y + o.y, z + o.z}; }
  constexpr Vec3T operator-(const Vec3T& o) const { return {x - o.x, y - o.y, z - o.z}; }
  constexpr Vec3T operator-() const { return {-x, -y, -z}; }
  constexpr Vec3T operator*(T s) const { return {x * s, y * s, z * s}; }
  constexpr Vec3T operator/(T s) const { return {x / s, y / s, z / s}; }
  constexpr Vec3T operator*(const Vec3T& o) const { return {x * o.x, y * o.y, z * o.z}; }
  constexpr Vec3T& operator+=(const Vec3T& o) {
    x += o.x;
    y += o.y;
    z += o.z;
    return *this;
  }
  constexpr Vec3T& operator-=(const Vec3T& o) {
    x -= o.x;
    y -= o.y;
    z -= o.z;
    return *this;
  }
  constexpr Vec3T& operator*=(T s) {
    x *= s;
    y *= s;
    z *= s;
    return *this;
  }
  constexpr bool operator==(const Vec3T& o) const = default;
};

using Vec3 = Vec3T<float>;
using Vec3d = Vec3T<double>;

template <typename T>
constexpr Vec3T<T> operator*(T s, const Vec3T<T>& v) {
  return v * s;
}
template <typename T>
constexpr T Dot(const Vec3T<T>& a, const Vec3T<T>& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
template <typename T>
constexpr Vec3T<T> Cross(const Vec3T<T>& a, const Vec3T<T>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
template <typename T>
constexpr T LengthSquared(const Vec3T<T>& v) {
  return Dot(v, v);
}
template <typename T>
inline T Length(const Vec3T<T>& v) {
  return std::sqrt(Dot(v, v));
}
template <typename T>
inline Vec3T<T> Normalize(const Vec3T<T>& v) {
  return v / Length(v);
}
template <typename T>
constexpr Vec3T<T> Min(const Vec3T<T>& a, const Vec3T<T>& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)};
}
template <typename T>
constexpr Vec3T<T> Max(const Vec3T<T>& a, const Vec3T<T>& b) {
  return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)};
}
template <typename T>
constexpr T MaxComponent(const Vec3T<T>& v) {
  return std::max(v.x, std::max(v.y, v.z));
}
template <typename T>
inline bool IsFinite(const Vec3T<T>& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Linear RGB radiometric quantity (radiance, power, reflectance). Kept distinct from Vec3 so
// that colours and directions never mix by accident.
struct Rgb {
  float r = 0, g = 0, b = 0;

  constexpr Rgb() = default;
  constexpr Rgb(float r_, float g_, float b_) : r(r_), g(g_), b(b_) {}
  constexpr explicit Rgb(float v) : r(v), g(v), b(v) {}

  constexpr float operator[](int i) const { return i == 0 ? r : (i == 1 ? g : b); }
  constexpr float& operator[](int i) { return i == 0 ? r : (i == 1 ? g : b); }
  constexpr Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
  constexpr Rgb operator-(const Rgb& o) const { return {r - o.r, g - o.g, b - o.b}; }
  constexpr Rgb operator*(const Rgb& o) const { return {r * o.r, g * o.g, b * o.b}; }
  constexpr Rgb operator/(const Rgb& o) const { return {r / o.r, g / o.g, b / o.b}; }
  constexpr Rgb operator*(float s) const { return {r * s, g * s, b * s}; }
  constexpr Rgb operator/(float s) const { return {r / s, g / s, b / s}; }
  constexpr Rgb& operator+=(const Rgb& o) {
    r += o.r;
    g += o.g;
    b += o.b;
    return *this;
  }
  constexpr Rgb& operator*=(const Rgb& o) {
    r *= o.r;
    g *= o.g;
    b *= o.b;
    return *this;
  }
  constexpr Rgb& operator*=(float s) {
    r *= s;
    g *= s;
    b *= s;
    return *this;
  }
  constexpr bool operator==(const Rgb& o) const = default;

  constexpr float Max() const { return std::max(r, std::max(g, b)); }
  constexpr float Mean() const { return (r + g + b) * (1.0f / 3.0f); }
  // Rec. 709 luminance weights.
  constexpr float Luminance() const { return 0.2126f * r + 0.7152f * g + 0.0722f * b; }
  constexpr bool IsBlack() const { return r == 0 && g == 0 && b == 0; }
  bool IsFinite() const { return std::isfinite(r) && std::isfinite(g) && std::isfinite(b); }
};
constexpr Rgb operator*(float s, const Rgb& c) {
  return c * s;
}

// sin(2πu) and cos(2πu) for u in [0, 1] (the samplers' range; outside it the reduction below is
// not exact), without a libm call: the azimuth of the photon walk's cosine lobes (Wald 1999,
// §2.2), one per photon ray (libm's sincosf there and EvalPdf in the roulette weight were 4 % of
// a trace's instructions together: docs/results/kernel.md §4). u·4 = q + x with q an integer (u·4 is exact,
// and so is x = u·4 − q) and |x| <= ½ (+ rounding of the + ½), so 2πu = q·π/2 + θ with θ = x·π/2 in [−π/4,
// π/4], where the Taylor polynomials of sin to θ⁹ and of cos to θ⁸ leave < 3e-8 (half an ulp of 1); the
// quadrant q mod 4 swaps and negates them. Plain float operations, never contracted to FMA
// (-ffp-contract=off, CMakeLists.txt): the same bits on every build.
// Within 2.5e-7 of sin and cos (test SinCos2Pi.MatchesDoublePrecision).
inline void SinCos2Pi(float u, float* sin_out, float* cos_out) {
  const float a = u * 4.0f;
  const float q = std::floor(a + 0.5f);  // = int(a + ½) on [0, 1]; no int overflow elsewhere
  const float x = a - q, x2 = x * x;
  const float sp =
      x *
      (1.5707963f + x2 * (-0.64596410f + x2 * (0.079692626f + x2 * (-0.0046817541f + x2 * 0.00016044118f))));
  const float cp =
      1.0f + x2 * (-1.2337006f + x2 * (0.25366951f + x2 * (-0.020863481f + x2 * 0.00091926027f)));
  const int quadrant = int(q) & 3;
  const float s0 = (quadrant & 1) ? cp : sp, c0 = (quadrant & 1) ? sp : cp;
  *sin_out = (quadrant & 2) ? -s0 : s0;
  *cos_out = (quadrant == 1 || quadrant == 2) ? -c0 : c0;
}

// Cosine-weighted direction about +z (local frame) for the particle walks (photons, importons:
// Bsdf::Mode::kRussianRoulette, and the photons' emission), with SinCos2Pi's azimuth: the same
// distribution as r·(cos 2πu2, sin 2πu2), r = √u1, z = √(1 − u1), to within SinCos2Pi's 2.5e-7.
inline Vec3 CosineHemisphereFast(float u1, float u2) {
  const float r = std::sqrt(u1);
  float s, c;
  SinCos2Pi(u2, &s, &c);
  return {r * c, r * s, std::sqrt(std::max(0.0f, 1.0f - u1))};
}

// Orthonormal basis around a unit normal (Duff et al. 2017, branchless).
struct Frame {
  Vec3 s, t, n;
  Frame() = default;
  explicit Frame(const Vec3& normal) : n(normal) {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float b = n.x * n.y * a;
    s = {1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x};
    t = {b, sign + n.y * n.y * a, -n.y};
  }
  Vec3 ToLocal(const Vec3& v) const { return {Dot(v, s), Dot(v, t), Dot(v, n)}; }
  Vec3 ToWorld(const Vec3& v) const { return s * v.x + t * v.y + n * v.z; }
};

struct Bounds3 {
  Vec3 lo{std::numeric_limits<float>::max()};
  Vec3 hi{-std::numeric_limits<float>::max()};
  void Extend(const Vec3& p) {
    lo = Min(lo, p);
    hi = Max(hi, p);
  }
  void Extend(const Bounds3& b) {
    lo = Min(lo, b.lo);
    hi = Max(hi, b.hi);
  }
  bool Empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
  Vec3 Diagonal() const { return Empty() ? Vec3(0) : hi - lo; }
  Vec3 Center() const { return (lo + hi) * 0.5f; }
};

}  // namespace pf
