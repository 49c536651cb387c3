#pragma once
// How hard the light that mirrors and glass focus (caustics, L S+ D: Wald 1999, §2.2) is for a
// path tracer: the second pilot behind `integrator auto` (integrator_choice.h; docs/renderer.md,
// "Choosing the integrator"). A path tracer finds a caustic only when a ray it samples from a
// diffuse point, after the mirrors and glass on its way, happens to end on a light: often for a
// sky, which fills half the directions, rarely for a small lamp (noise), never for a point, spot
// or directional light (the caustic is missing from its image). Photons find all three alike, so
// the pilot traces photons and asks what a path tracer's samples would make of the caustic
// irradiance they bring. Deterministic: the same scene and camera give the same numbers on every
// thread count.

#include "common/camera/camera.h"
#include "common/render/scene_runtime.h"

namespace pf {

struct CausticReach {
  // Camera rays of a lattice over the image that reach, directly or through mirrors and glass, a
  // surface with a non-delta lobe: their first such hits y.
  int points = 0;
  // A path-traced sample of the caustic at y (a cosine-distributed ray through the mirrors and
  // glass that ends on a light of radiance Le with throughput T) is π·T·Le, with the probability
  // that makes its mean the caustic irradiance Ec(y) = Σ Φ/(π r²) of the caustic photons around y;
  // its second moment is then Σ π·T·Le·Φ/(π r²) over the same photons, each with its own T·Le.
  // (A lower bound: the path tracer's lobe choice at a diffuse-and-glossy y and its Russian
  // roulette on long chains add to it.) The mean over the points of that sample's variance /
  // (direct + caustic irradiance)², the direct one from shadow rays as the path tracer's: the
  // squared relative noise the caustics add to a path-traced pixel per sample, where the viewer
  // sees it (a dim wall's fireflies count as much as a bright floor's; each point at most 100).
  double relative_caustic_variance = 0.0;
  // Σ over the points of Ec / Σ of the direct + caustic irradiance.
  double caustic_fraction = 0.0;
  // Of the power photons bring to surfaces with a diffuse lobe, directly or through the delta lobes
  // of mirrors and glass (luminance, the whole scene), the part that comes from punctual lights
  // (point, spot, directional) through at least one of those lobes: light a path tracer cannot find.
  double punctual_caustic_share = 0.0;
};

// `grid` × `grid` camera rays, `shadow_rays` per point, `photons` photons emitted as the photon map
// emits them (followed through delta lobes only).
CausticReach MeasureCausticReach(const SceneRuntime& scene, const Camera& camera, int grid = 32,
                                 int shadow_rays = 128, int photons = 1 << 16);

}  // namespace pf
