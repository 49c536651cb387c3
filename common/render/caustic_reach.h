#pragma once
// How hard the light that mirrors and glass focus (caustics, L S+ D: Wald 1999, §2.2) is for a
// path tracer: the second pilot behind `integrator auto` (integrator_choice.h; docs/renderer.md,
// "Choosing the integrator"). A path tracer finds a caustic only when a ray it samples from a
// diffuse point, after the mirrors and glass on its way, happens to end on a light: often for a
// sky, which fills half the directions, rarely for a small lamp (noise), never for a point, spot
// or directional light (the caustic is missing from its image). Photons find all three alike, so
// the pilot traces photons and asks what a path tracer's samples would make of the caustic
// irradiance they bring. Deterministic: the same scene and camera give the same numbers on every
// machine and thread count.

#include "common/camera/camera.h"
#include "common/render/scene_runtime.h"

namespace pf {

struct CausticReach {
  // At the first diffuse hit y of a lattice of camera rays (as LightReach's points):
  int points = 0;
  // A path-traced sample of the caustic at y (a cosine-distributed ray through the mirrors and
  // glass that ends on a light of radiance Le with throughput T, probability p) is π·T·Le: its mean
  // is the caustic irradiance Ec(y) = Σ Φ/(π r²) of the caustic photons around y, its second moment
  // Σ π·T·Le·Φ/(π r²) over the same photons. Σ over the points of that sample's variance / Σ of
  // (direct + caustic irradiance)², the direct one from shadow rays as the path tracer's:
  // the squared relative noise the caustics add to a path-traced pixel per sample.
  double relative_caustic_variance = 0.0;
  // Σ over the points of Ec / Σ of the direct + caustic irradiance.
  double caustic_fraction = 0.0;
  // Of the power photons bring to their first surface with a diffuse lobe (luminance, the whole
  // scene), the part that comes from punctual lights (point, spot, directional) through at least
  // one mirror or glass: light a path tracer cannot find at all.
  double punctual_caustic_share = 0.0;
};

// `grid` × `grid` camera rays, `shadow_rays` per point, `photons` photons emitted as the photon map
// emits them (followed through delta lobes only).
CausticReach MeasureCausticReach(const SceneRuntime& scene, const Camera& camera, int grid = 32,
                                 int shadow_rays = 32, int photons = 1 << 16);

}  // namespace pf
