#pragma once
// MGF transforms (mgfdoc.tr §2.2.2, §2.2.3, §3 xf): rigid motions with uniform scale and
// mirrors as 3×4 affine maps, and the parsed form of one `xf` specification with its arrays.

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/core/math.h"

namespace pf::mgf {

// Transforms (§2.2.2, §2.2.3): rigid motions with uniform scale and mirrors, as 3×4 affine maps.
struct Affine {
  double m[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Vec3d t;

  Vec3d Vector(const Vec3d& v) const {
    return {m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z};
  }
  Vec3d Point(const Vec3d& p) const { return Vector(p) + t; }
  double Det() const {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  }
  // Uniform scale factor (length of the first column; hypot avoids overflow).
  double Scale() const { return std::hypot(m[0][0], m[1][0], m[2][0]); }
  // True if the map contains a mirror (negative determinant), computed on the normalised
  // matrix so that huge or tiny scales cannot overflow it.
  bool Mirrors() const {
    const double s = Scale();
    if (!(s > 0.0) || !std::isfinite(s)) return false;
    Affine n = *this;
    for (auto& row : n.m)
      for (double& v : row) v /= s;
    return n.Det() < 0.0;
  }
  bool IsFinite() const {
    for (const auto& row : m)
      for (double v : row)
        if (!std::isfinite(v)) return false;
    return pf::IsFinite(t);
  }
};

// The map "first b, then a".
Affine Compose(const Affine& a, const Affine& b);

// a applied n times (n >= 0; the identity for n = 0).
Affine Power(Affine a, long n);

// Rotation by `degrees` counter-clockwise about axis `axis` (right-hand rule, §2.2.2); exact
// for multiples of 90° so that axis-aligned models stay axis-aligned.
Affine Rotation(int axis, double degrees);

// One transform specification: a sequence of segments, each a composed step applied `count`
// times (`-i N`, and the arguments before the first -a/-i with count 1) or applied 0..N-1 times
// over the instances of an array (`-a N`). "The scope of an array command continues until the
// next -i or -a option" (§2.2.3).
struct XformSegment {
  bool array = false;
  long count = 1;
  Affine step;
};
struct XformSpec {
  std::vector<XformSegment> segments;
  uint64_t instances = 1;
  size_t NumArrays() const {
    size_t n = 0;
    for (const auto& s : segments) n += s.array;
    return n;
  }
  // The transform of the instance with the given array counters (one per -a segment).
  Affine Instance(const std::vector<long>& counters) const;
};

// Odometer over the array counters; false once every instance has been produced.
bool AdvanceCounters(const XformSpec& spec, std::vector<long>& counters);

}  // namespace pf::mgf
