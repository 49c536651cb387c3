#pragma once
// Rays, hits and the robust ray-origin offset. No Embree here: accel/embree_scene.cpp is the
// only file that includes Embree (docs/design.md, S3: one place per third-party library).

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#if defined(__SSE4_1__)
#include <immintrin.h>
#endif

#include "common/core/math.h"
#include "common/scene/texture.h"

namespace pf {

struct Ray {
  Vec3 origin;
  Vec3 direction;  // unit length
  float t_max = std::numeric_limits<float>::infinity();
};

// A surface hit, already resolved against the scene description.
struct SurfaceHit {
  float t = 0.0f;
  uint32_t triangle = 0;
  Vec3 position;          // interpolated from the vertices (more accurate than o + t·d)
  Vec3 geometric_normal;  // unit normal of the triangle's front face (vertex order, right hand)
  Vec3 shading_normal;    // unit, interpolated vertex normal (or geometric), same side as ng
  uint32_t material = 0;
  uint32_t light = 0xffffffffu;  // kNoLight unless the triangle emits
  bool front_face = true;        // the ray arrived on the front side
  TextureCoordinates uv{};       // interpolated; (0, 0) when the scene has none (texture.h)
};

// What a particle walk (the photon walk of Wald 1999, §2.2) reads of a hit: SurfaceHit's fields
// of the same names, with the same values, and none of the rest (t, triangle, front face, light),
// which EmbreeScene::IntersectWalk does not look up (docs/results/kernel.md §4).
struct WalkHit {
  Vec3 position;
  Vec3 geometric_normal;
  Vec3 shading_normal;
  uint32_t material = 0;
  bool interpolated = false;  // shading_normal came from vertex normals (else it is ng, bit for bit)
  TextureCoordinates uv{};    // as SurfaceHit's
};

// The next float above / below a finite v, by its bits (std::nextafter is a libm call; this is
// on every spawned ray's path). -0 and +0 step to the smallest subnormal of the right sign.
inline float NextFloatUp(float v) {
  uint32_t b = std::bit_cast<uint32_t>(v);
  if (b == 0x80000000u) b = 0;  // -0 → +0
  b = v >= 0.0f ? b + 1 : b - 1;
  return std::bit_cast<float>(b);
}
inline float NextFloatDown(float v) {
  uint32_t b = std::bit_cast<uint32_t>(v);
  if (b == 0) b = 0x80000000u;  // +0 → -0
  b = v > 0.0f ? b - 1 : b + 1;
  return std::bit_cast<float>(b);
}

// Spacing of floats at |v|: one unit in the last place (ulp). Finite for every finite v.
inline float Ulp(float v) {
  const float a = std::fabs(v);
  const float next = NextFloatUp(a);
  return std::isfinite(next) ? next - a : a - NextFloatDown(a);
}

// Ray origins are moved off their surface by a bound on the rounding error of the surface
// point, so that the next ray cannot hit the surface it leaves (self-intersection: acne,
// self-shadowing) and yet misses no geometry nearby (light leaks in corners).
//
// The error of a point is relative to the *magnitude of its coordinates*, not to the size of
// the scene: a 2 m room translated 1e6 m from the origin is drawn on a float lattice of
// 6.25 cm. Hit points and light samples are interpolated in double from the triangle's float
// vertices (a + u·(b−a) + v·(c−a) lies on the triangle's plane) and rounded once, so each
// coordinate is within ½ ulp of the plane's point; projected on the normal n that is at most
// ½·(|nx|+|ny|+|nz|)·ulp(max |p_i|). The offset is kRayOffsetUlps times the full ulp of that
// (4× the bound), and the moved point is then rounded away from p in each component that moved
// (as pbrt-v4 does), so the rounding of p + offset cannot undo it. Embree intersects in
// coordinates relative to the ray origin (v0 − o is exact for nearby points), so its own error
// scales with the triangle, not with the coordinates: the scene floor `scene_epsilon` (a
// millionth of the scene's diagonal) covers it, and points near the origin of a large scene.
//
// Before (docs/renderer.md): a fixed 2^-15 of the largest coordinate, 256 ulps: 3 m at 1e5, 30 m at
// 1e6, which threw rays out of a translated room (docs/results/hard_cases.md).
inline constexpr float kRayOffsetUlps = 2.0f;

// The offset along a unit vector `direction` at p (see above).
inline float RayOffset(const Vec3& p, const Vec3& direction, float scene_epsilon) {
  const float magnitude = MaxComponent(Vec3(std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)));
  const float l1 = std::fabs(direction.x) + std::fabs(direction.y) + std::fabs(direction.z);
  return std::max(kRayOffsetUlps * l1 * Ulp(magnitude), scene_epsilon);
}
// The largest offset over all directions (|n|₁ ≤ √3): how far an offset origin may be from p.
inline float RayOffset(const Vec3& p, float scene_epsilon) {
  const float magnitude = MaxComponent(Vec3(std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)));
  return std::max(kRayOffsetUlps * std::numbers::sqrt3_v<float> * Ulp(magnitude), scene_epsilon);
}

// Moves a surface point off its surface along `normal` (unit, pointing to the side the next
// ray leaves from) by RayOffset, rounding each moved coordinate away from p.
inline Vec3 OffsetRayOriginScalar(const Vec3& p, const Vec3& normal, float scene_epsilon) {
  const Vec3 offset = normal * RayOffset(p, normal, scene_epsilon);
  Vec3 q = p + offset;
  for (int i = 0; i < 3; ++i) {
    if (offset[i] > 0.0f) q[i] = NextFloatUp(q[i]);
    if (offset[i] < 0.0f) q[i] = NextFloatDown(q[i]);
  }
  return q;
}
#if defined(__SSE4_1__)
// The same bits as OffsetRayOriginScalar for a finite p and normal (test
// HardCasesRayOffset.OffsetRayOriginStepsEachMovedCoordinateAway; a NaN may come out with another sign bit),
// without its six data-dependent branches per ray: which coordinates move up or down depends on
// the normal's signs, which a photon walk or a path changes at every bounce, so they were
// mispredicted at every spawned ray (docs/results/kernel.md §4). The steps of NextFloatUp/Down
// on all three coordinates at once: −0 → +0 (up) or +0 → −0 (down), then ±1 on the bits.
inline Vec3 OffsetRayOrigin(const Vec3& p, const Vec3& normal, float scene_epsilon) {
  const float step = RayOffset(p, normal, scene_epsilon);
  const __m128 offset = _mm_mul_ps(_mm_setr_ps(normal.x, normal.y, normal.z, 0.0f), _mm_set1_ps(step));
  const __m128 q = _mm_add_ps(_mm_setr_ps(p.x, p.y, p.z, 0.0f), offset);
  const __m128 zero = _mm_setzero_ps();
  const __m128i bits = _mm_castps_si128(q), sign = _mm_set1_epi32(int(0x80000000u)), one = _mm_set1_epi32(1);
  // Up: b (−0 as +0) + 1 where q >= 0, − 1 elsewhere: b − 2·mask − 1 with mask = −1 or 0.
  const __m128i up_base = _mm_andnot_si128(_mm_cmpeq_epi32(bits, sign), bits);
  const __m128i ge = _mm_castps_si128(_mm_cmpge_ps(q, zero));
  const __m128i up = _mm_sub_epi32(_mm_sub_epi32(up_base, _mm_add_epi32(ge, ge)), one);
  // Down: b (+0 as −0) − 1 where q > 0, + 1 elsewhere: b + 2·mask + 1.
  const __m128i down_base =
      _mm_or_si128(bits, _mm_and_si128(_mm_cmpeq_epi32(bits, _mm_setzero_si128()), sign));
  const __m128i gt = _mm_castps_si128(_mm_cmpgt_ps(q, zero));
  const __m128i down = _mm_add_epi32(_mm_add_epi32(down_base, _mm_add_epi32(gt, gt)), one);
  __m128i r = _mm_blendv_epi8(bits, down, _mm_castps_si128(_mm_cmplt_ps(offset, zero)));
  r = _mm_blendv_epi8(r, up, _mm_castps_si128(_mm_cmpgt_ps(offset, zero)));
  alignas(16) float out[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(out), r);
  return {out[0], out[1], out[2]};
}
#else
inline Vec3 OffsetRayOrigin(const Vec3& p, const Vec3& normal, float scene_epsilon) {
  return OffsetRayOriginScalar(p, normal, scene_epsilon);
}
#endif

// p0 + u·(p1 − p0) + v·(p2 − p0) in double, rounded once: a point of the triangle's plane to
// within ½ ulp per coordinate, whatever the magnitude of the coordinates (see above).
inline Vec3 InterpolateOnTriangle(const Vec3& p0, const Vec3& p1, const Vec3& p2, double u, double v) {
  const Vec3d a(p0);
  return Vec3(a + (Vec3d(p1) - a) * u + (Vec3d(p2) - a) * v);
}

}  // namespace pf
