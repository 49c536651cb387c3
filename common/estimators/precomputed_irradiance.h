#pragma once
// Precomputed irradiance for final gathering (Christensen 1999, "Faster Photon Map Global
// Illumination"): the local pass (Wald 1999, §4.3) reads the photon maps at the hit of every
// gather ray, i.e. N_lp full k-NN radiance estimates per camera sample. Instead, the
// irradiance E is estimated once per map at a subset of the photon positions ("sites", every
// `stride`-th photon of the global map and of the direct map when it is separate), and a
// gather hit y then costs one nearest-site lookup: L(y) = ρd(y)/π · E(site) (here: the mean E
// of the few nearest sites visible from y, see below).
//
// Sites are stored as 18-byte photons in a photon map of their own (bucket_kdtree.h): the
// position is the site's, the "direction" bytes hold the site's surface normal on its lit side
// (0.8° quantisation, photon.h) and the "power" bytes E in RGBE (2^-8 relative). The photon
// record does not carry a surface normal, so each site finds its own with one short ray along
// the photon's incoming direction through its position (the photon was stored where that ray
// hit). A lookup takes the `candidates` nearest sites whose normal agrees with y's side
// (cos ≥ normal_cos, in-query filter, §4.1) within max_radius, keeps those visible from y (a
// shadow ray each, as the occlusion test of §4.1.1: a site may lie across a thin wall, in a
// brighter room) and averages the first `average` of them; without one the caller falls back
// to the full estimate.
//
// Bias: E is the estimate at the sites, not at y (an interpolation over a distance of about
// the photon spacing times √(stride·average)) and is RGBE-rounded; both are far below
// the k-NN estimate's own blur radius. Measured in docs/results/local_pass.md.
//
// Determinism: each site's E is a pure function of the maps (the estimate involves no random
// numbers), computed in parallel into its own slot; the site map is built sequentially from
// the sites in photon order. Same maps → same sites, bit for bit, for any thread count.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>

#include "common/accel/embree_scene.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_map.h"
#include "common/photon/photon_maps.h"

namespace pf {

struct PrecomputedIrradianceOptions {
  int stride = 4;                     // every stride-th photon is a site (Christensen 1999 uses 4)
  float normal_cos = 0.75f;           // a site serves y only if cos(normal_site, normal_y) ≥ this
  float max_radius_fraction = 0.05f;  // lookup radius, fraction of the scene's diagonal
  // Candidates per lookup: the nearest `candidates` agreeing sites are tried in distance
  // order, one shadow ray each, and only visible ones serve (`average` below): a site behind a
  // wall would carry the other room's light into this one. 0 = no visibility test (nearest).
  int candidates = 4;
  // Of those, the first `average` visible ones are averaged (1 = the nearest visible site, as
  // Christensen 1999). Each site's E is a k-NN estimate with its own noise, and a gather hit
  // reading one site repeats that noise over the site's whole neighbourhood; the mean of 4
  // spreads over the area of about 4·stride = 16 photons, well inside the k = 50 disk each
  // site already averages over. Low budget (100k photons, k = 50), RMSE/white: Cornell 0.01863
  // (nearest) → 0.01844 (4; the full local pass 0.01856), INVISIBLEDATE 0.4506 → 0.4523, for
  // +5-13 % CPU time: docs/results/kernel.md §2.
  int average = 4;
  // The sites' own estimates drop photons whose incoming path the site cannot see (Wald 1999, §4.1.1;
  // needs photon origins in the maps: ConfigureMapsFor keeps them). Read by the photon map
  // integrator, which builds the sites (Build itself only calls the RadianceFn). Without it the
  // sites next to a wall carry the light of the room behind it into every gather that reads
  // them (INVISIBLEDATE low budget: RMSE/white 0.570 without, 0.483 with, the full local pass
  // 0.558); where nothing bleeds it only darkens the sites in corners a little (scene8 0.0184 →
  // 0.0189). docs/results/kernel.md §2.
  bool occlusion_test = true;
  int threads = 0;  // for the precomputation; 0 = TBB's default
};

class PrecomputedIrradiance {
 public:
  // radiance(white, x, n): the photon-map radiance leaving x along n through the diffuse
  // reflection of `white` (a white Lambertian BSDF with normal n): E(x) = π · radiance.
  // Called concurrently from several threads.
  using RadianceFn = std::function<Rgb(const Bsdf& white, const Vec3& x, const Vec3& n)>;
  static std::shared_ptr<const PrecomputedIrradiance> Build(const EmbreeScene& scene, const PhotonMaps& maps,
                                                            const PrecomputedIrradianceOptions& options,
                                                            const RadianceFn& radiance);

  // Irradiance at y on the side facing unit normal n, or nullopt when no site qualifies.
  std::optional<Rgb> Lookup(const Vec3& y, const Vec3& n, NearestPhotons& nearest) const;

  std::size_t sites() const { return sites_ ? sites_->size() : 0; }
  double build_seconds() const { return build_seconds_; }
  const PhotonMap& site_map() const { return *sites_; }

 private:
  std::unique_ptr<PhotonMap> sites_;
  const EmbreeScene* scene_ = nullptr;
  int candidates_ = 4;
  int average_ = 4;
  float normal_cos_ = 0.75f;
  float max_radius_ = 0.0f;
  double build_seconds_ = 0.0;
};

}  // namespace pf
