#include "common/core/real_text.h"

#include <fmt/format.h>

namespace pf {

std::string RealText(double v) {
  // fmt's "{}" is the shortest round-trip text of the argument's own type (Ryu-like).
  return double(float(v)) == v ? fmt::format("{}", float(v)) : fmt::format("{}", v);
}

std::string RealText(const Vec3d& v) {
  return RealText(v.x) + "," + RealText(v.y) + "," + RealText(v.z);
}

}  // namespace pf
