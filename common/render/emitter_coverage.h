#pragma once
// Where a camera sees emitters directly (docs/renderer.md, "Sampling and determinism": the masked error
// metrics of `pf diff` and the convergence study). Geometric, from the scene itself rather than from an
// image's brightness: a luminance threshold would take a brightly lit wall for a light and miss a dim light
// (the CornellBox-Sphere light has radiance 1, less than some lit surfaces elsewhere), while the scene knows
// exactly which surfaces emit.

#include <vector>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"

namespace pf {

// Per pixel (y·W + x), the fraction of a grid x grid lattice of camera rays (through the centres
// of the pixel's sub-cells) whose first hit is the front face of an emitter: 1 inside a visible
// light, 0 away from it, in between on its border.
std::vector<float> EmitterCoverage(const EmbreeScene& scene, const Camera& camera, int grid = 4);

}  // namespace pf
