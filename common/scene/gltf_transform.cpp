#include "common/scene/gltf_transform.h"

#include <cmath>

namespace pf {

mgf::Affine GltfTrs(const std::vector<double>& translation, const std::vector<double>& rotation,
                    const std::vector<double>& scale) {
  mgf::Affine a;
  if (rotation.size() == 4) {
    double x = rotation[0], y = rotation[1], z = rotation[2], w = rotation[3];
    const double norm = std::sqrt(x * x + y * y + z * z + w * w);
    if (norm > 0.0 && std::isfinite(norm)) {
      x /= norm, y /= norm, z /= norm, w /= norm;
      a.m[0][0] = 1 - 2 * (y * y + z * z), a.m[0][1] = 2 * (x * y - z * w), a.m[0][2] = 2 * (x * z + y * w);
      a.m[1][0] = 2 * (x * y + z * w), a.m[1][1] = 1 - 2 * (x * x + z * z), a.m[1][2] = 2 * (y * z - x * w);
      a.m[2][0] = 2 * (x * z - y * w), a.m[2][1] = 2 * (y * z + x * w), a.m[2][2] = 1 - 2 * (x * x + y * y);
    }
  }
  if (scale.size() == 3)
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a.m[r][c] *= scale[size_t(c)];
  if (translation.size() == 3) a.t = Vec3d(translation[0], translation[1], translation[2]);
  return a;
}

}  // namespace pf
