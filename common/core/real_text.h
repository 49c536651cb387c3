#pragma once
// Real numbers as text that reads back to the same value (docs/settings.md, "In the EXR header"):
// a value that is exactly a float — a float field widened to double, or a double holding a float,
// such as a camera read from an MGF scene — is written as the float's shortest text ("3.9", which
// strtof reads back to 3.9f), any other as the double's shortest text (strtod reads it back).
// So 3.9f is "3.9", never "3.9000000953674316", and two values one float step apart differ.

#include <string>

#include "common/core/math.h"

namespace pf {

std::string RealText(double v);
// "x,y,z", each component as RealText.
std::string RealText(const Vec3d& v);

}  // namespace pf
