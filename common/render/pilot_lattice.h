#pragma once
// The camera rays of the integrator's pilots (light_reach.h, caustic_reach.h): one through the
// centre of each cell of a grid × grid lattice over the image, whatever its aspect, so a pilot's
// cost does not grow with the resolution and the same scene and camera give the same rays.

#include <algorithm>

#include "common/camera/camera.h"

namespace pf {

inline Ray PilotLatticeRay(const Camera& camera, int grid, int i, int j) {
  const float fx = (float(i) + 0.5f) / float(grid) * float(camera.width());
  const float fy = (float(j) + 0.5f) / float(grid) * float(camera.height());
  const int px = std::min(int(fx), camera.width() - 1), py = std::min(int(fy), camera.height() - 1);
  return camera.GenerateRay(px, py, fx - float(px), fy - float(py));
}

}  // namespace pf
