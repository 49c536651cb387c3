#pragma once
// The radiance estimate (Wald 1999, §2.5, §3) with the feasibility tests of §4.1:
//
//   L_r(x, ω) ≈ Σ_p f_r(x, ω_p, ω) ΔΦ_p / (π r²),   r = distance to the k-th nearest photon.
//
// Feasibility tests (§4.1), applied either *inside* the query (only feasible photons enter the
// heap, so k are found whenever k feasible ones exist) or *after* it (cheap: exactly the k
// nearest are tested, fewer may remain; r stays the k-th distance):
//  * direction vs normal: the photon must arrive from the viewer's side of the surface
//    (skipped for materials that transmit diffusely, which see both sides);
//  * caustic threshold: with a maximum search radius, discard the whole estimate when fewer
//    than `min_fraction`·k photons are found (removes stray caustic photons; loses energy).
// With a maximum radius R and fewer than k photons inside it, r = R: the disk searched.

#include <cstdint>
#include <limits>

#include <span>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_map.h"

namespace pf {

enum class FeasibilityTest { kNone, kInQuery, kAfterQuery };

// How far back along a photon's incoming path the occlusion test looks, in search radii. Any
// positive value keeps a wall between x and the photon in the way (the path is on the photon's
// side of it); 2 leaves a margin for a photon that just passed an edge. On INVISIBLEDATE 2 and 8
// gave the same image mean and errors within 5 % (docs/results/occlusion-test.md).
inline constexpr float kOcclusionReach = 2.0f;

struct RadianceEstimateOptions {
  int k = 100;
  float max_radius = std::numeric_limits<float>::infinity();
  FeasibilityTest direction_test = FeasibilityTest::kInQuery;
  float min_fraction = 0.0f;  // caustic threshold; 0 = off
  // The k-th photon only defines r. Counting its power too (the thesis's Σ over all k) biases
  // a uniform photon density high by k/(k−1): for a Poisson density λ, πr²λ of the k-th
  // neighbour is Gamma(k)-distributed and E[1/Gamma(k)] = 1/(k−1). Excluding it makes the
  // estimate of a uniform density unbiased (furnace test). false = the thesis's formula.
  bool exclude_boundary_photon = true;
  // Occlusion testing (§4.1.1): after the query, drop every photon whose incoming path is not
  // visible from x where it ends — the point kOcclusionReach search radii back along it, or the
  // origin (previous path vertex) when nearer; one shadow ray per photon. Needs photon origins.
  bool occlusion_test = false;
  // Adaptive k (§4.8): query k photons, then use only the nearest k' ≤ k of them where their
  // centre of gravity is off x (near borders of shadows, caustics, walls). With
  // d = |cog − x| / r:   k' = k                                    for d ≤ d0 = 2/√k (noise)
  //                       k' = k − (k − k_min)·(d − d0)/(d1 − d0)   for d0 < d < d1
  //                       k' = k_min                                for d ≥ d1 = 4/(3π)
  // d1 is the centre of gravity of a half disk: x exactly on a straight border. d0 ≈ 4σ of
  // |cog − x|/r for k uniform photons in a disk. For k ≤ 22, d0 ≥ d1: noise alone cannot be
  // told from a border and the rule keeps k (adaptive k is off). 0 = off.
  int adaptive_k_min = 0;
  // Progressive photon mapping's pass estimate (Knaus & Zwicker 2011, §4; docs/renderer.md,
  // "Progressive plan"): every feasible photon within max_radius (PhotonMap::QueryRadius), none
  // excluded, over the disk π max_radius²; k, min_fraction and adaptive k are not used.
  bool radius_query = false;
};

// What an estimate may need beyond the map: per-photon attributes and the scene for shadow rays.
struct EstimateContext {
  const std::vector<Vec3>* origins = nullptr;  // for occlusion_test (post-build order)
  const EmbreeScene* scene = nullptr;          // for occlusion_test
  // Searched first (PhotonMap::QueryWithHint): when the ball of this radius holds k feasible
  // photons they are exactly the k nearest, found with most of the tree culled; otherwise the
  // query runs again unhinted. The same photons either way (their heap order, and so the last
  // bits of the sum, may differ). 0 = no hint.
  float radius_hint = 0.0f;
};

struct RadianceEstimateResult {
  Rgb radiance;
  int photons_used = 0;
  float radius2 = 0;
  int shadow_rays = 0;
};

// Estimates the radiance leaving x towards `wo` through the non-delta lobes in `lobes` of
// `bsdf`. `nearest` is the calling thread's query scratch.
RadianceEstimateResult EstimateRadiance(const PhotonMap& map, const Bsdf& bsdf, const Vec3& x, const Vec3& wo,
                                        uint32_t lobes, const RadianceEstimateOptions& options,
                                        NearestPhotons& nearest, const EstimateContext& context = {});

// The adaptive-k rule above: how many of the k nearest photons (sorted by distance) to use.
int AdaptiveK(const Vec3& x, std::span<const Vec3> nearest_sorted, int k_min);

}  // namespace pf
