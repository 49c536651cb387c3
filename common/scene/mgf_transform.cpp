// MGF transforms (mgf_transform.h); the spec is mgfdoc.tr (§2.2.2, §2.2.3).

#include "common/scene/mgf_transform.h"

#include <numbers>

namespace pf::mgf {

namespace {
constexpr double kPiD = std::numbers::pi;
}  // namespace

Affine Compose(const Affine& a, const Affine& b) {
  Affine r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      r.m[i][j] = a.m[i][0] * b.m[0][j] + a.m[i][1] * b.m[1][j] + a.m[i][2] * b.m[2][j];
  r.t = a.Point(b.t);
  return r;
}

Affine Power(Affine a, long n) {
  Affine r;
  while (n > 0) {
    if (n & 1) r = Compose(a, r);
    n >>= 1;
    if (n > 0) a = Compose(a, a);
  }
  return r;
}

Affine Rotation(int axis, double degrees) {
  double c, s;
  const double r = std::fmod(degrees, 360.0);
  if (r == std::floor(r / 90.0) * 90.0) {
    static constexpr double kCos[4] = {1, 0, -1, 0};
    static constexpr double kSin[4] = {0, 1, 0, -1};
    const int q = ((static_cast<int>(r / 90.0) % 4) + 4) % 4;
    c = kCos[q];
    s = kSin[q];
  } else {
    c = std::cos(r * kPiD / 180.0);
    s = std::sin(r * kPiD / 180.0);
  }
  Affine a;
  const int i = (axis + 1) % 3, j = (axis + 2) % 3;
  a.m[i][i] = c;
  a.m[i][j] = -s;
  a.m[j][i] = s;
  a.m[j][j] = c;
  return a;
}

Affine XformSpec::Instance(const std::vector<long>& counters) const {
  Affine r;
  size_t k = 0;
  for (const auto& s : segments) {
    const long n = s.array ? counters[k++] : s.count;
    r = Compose(Power(s.step, n), r);  // later arguments act on the already moved object
  }
  return r;
}

bool AdvanceCounters(const XformSpec& spec, std::vector<long>& counters) {
  size_t k = 0;
  for (const auto& s : spec.segments) {
    if (!s.array) continue;
    if (++counters[k] < s.count) return true;
    counters[k] = 0;
    ++k;
  }
  return false;
}

}  // namespace pf::mgf
