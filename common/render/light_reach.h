#pragma once
// How much of what a camera sees a light reaches directly: the pilot behind `integrator auto`
// (integrator_choice.h; docs/renderer.md, "Choosing the integrator"). A surface no light sees is
// lit only by paths of two or more bounces, which a path tracer finds by chance (its shadow
// rays all end on walls), while photons reach it along the way light went (Wald 1999, §2.2).
// Geometric and deterministic: the same scene and camera give the same fractions on every
// machine and thread count.

#include "common/camera/camera.h"
#include "common/render/scene_runtime.h"

namespace pf {

struct LightReach {
  int points = 0;  // camera rays that hit a surface neither emitting nor a perfect mirror or glass
  // Of those points, the fraction from which at least one of the shadow rays reaches a light
  // (its front side for an emitter, within a spot's cone): 1 in a room with its lamp in view
  // of every wall, near 0 for a room lit through a door.
  double lit_fraction = 0.0;
  // Of the points, the fraction that no light reaches but from which a photon search of radius
  // `leak_distance` would reach, through a wall, space that a light reaches (probe rays over the
  // visible hemisphere, followed through the first surface they meet and a wall's far face). A photon-map
  // estimate there finds the photons of the lit side: light bleeding (Wald 1999, §3.3.4), which the occlusion
  // test (§4.1.1) removes.
  double leak_fraction = 0.0;
};

// Traces a grid × grid lattice of camera rays over the image (one per cell centre) and, at each
// first hit, `shadow_rays` light samples (LightSampler::Sample with fixed hashed numbers);
// `leak_distance` (scene units, 0 = no leak test) is how far a photon search reaches.
LightReach MeasureLightReach(const SceneRuntime& scene, const Camera& camera, float leak_distance,
                             int grid = 64, int shadow_rays = 16);

}  // namespace pf
