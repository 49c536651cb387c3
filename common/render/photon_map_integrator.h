#pragma once
// The photon map shader in a distribution ray tracer (Wald 1999, §2.5): the "standalone"
// photon-map image (`--integrator photonmap`).
//
//  * Emitters are seen directly by camera rays and through singular (specular/glossy) paths.
//  * Singular lobes are followed by recursion: specular exactly, glossy by importance-sampled
//    Monte Carlo up to `glossy_depth` glossy bounces; beyond that the glossy lobe is
//    approximated by the photon-map estimate like the diffuse lobes (§2.5).
//  * Diffuse lobes read the global map (direct + indirect photons) and the caustic map; caustics
//    are always visualised directly from the caustic map.
// One sample per camera-path: the caller's samples per pixel average the stochastic choices.

#include <memory>

#include "common/estimators/radiance_estimate.h"
#include "common/photon/photon_maps.h"
#include "common/render/integrator.h"

namespace pf {

struct PhotonMapIntegratorOptions {
  RadianceEstimateOptions global;   // k nearest, unbounded radius by default
  RadianceEstimateOptions caustic;  // max radius + threshold (§4.1), see DefaultCausticOptions
  int glossy_depth = 1;             // glossy bounces followed before using the estimate
  int max_depth = 32;               // singular-chain cap (Russian roulette ends most earlier)
};

// Caustic estimate defaults: the same k, a maximum radius of 1 % of the scene's bounding-box
// diagonal, and the thesis's threshold of 10 % of k photons (§4.1).
RadianceEstimateOptions DefaultCausticOptions(int k, const Bounds3& scene_bounds);

class PhotonMapIntegrator final : public Integrator {
 public:
  PhotonMapIntegrator(const EmbreeScene& scene, const PhotonMaps& maps, PhotonMapIntegratorOptions options);
  Rgb Li(const Ray& camera_ray, Rng& rng, TraceCounters& counters) const override;
  const char* name() const override { return "photonmap"; }

 private:
  const EmbreeScene& scene_;
  const PhotonMaps& maps_;
  PhotonMapIntegratorOptions options_;
};

}  // namespace pf
