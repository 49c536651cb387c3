#pragma once
// The photon map shader in a distribution ray tracer (Wald 1999, §2.5) and the better
// estimators of chapter 4.
//
//  * Emitters are seen directly by camera rays and through singular (specular/glossy) paths;
//    so is the environment, by the rays that leave the scene. Its light on estimated lobes comes
//    from its photons (direct ones included, or through the direct-light estimators when direct
//    light is separate), like an area light's: counted once (§2.5).
//  * Singular lobes are followed by recursion: specular exactly, glossy by importance-sampled
//    Monte Carlo up to `glossy_depth` glossy bounces; beyond that the glossy lobe is
//    approximated by the photon-map estimate like the diffuse lobes (§2.5).
//  * At a surface whose diffuse lobes are estimated:
//      direct = kNone:  L = L_global (direct + indirect photons) + L_caustic   (standalone)
//      direct = MC or PhotonDirect (§4.2): L = L_d + L_i (global map without direct photons)
//                                                 + L_c (caustic map)
//    With the local pass (§4.3, `local_pass_rays` > 0) the first such surface replaces its
//    photon-map estimate of the non-caustic light by final gathering: N_lp rays sampled from the
//    diffuse lobes (cosine-weighted for Lambertian surfaces), each reading the maps at its hit y
//    (L(y) = global + direct photons + caustics at y, plus y's emission — or the environment's
//    for a ray that escapes — when direct light is not separate). Gather rays that hit a purely singular
//    surface add nothing: light reaching x through a mirror from a diffuse surface is a caustic path at x
//    (the thesis's definition, (S|D)* S+ D) and is already in x's caustic map.
// One sample per camera path: the caller's samples per pixel average the stochastic choices.

#include <memory>

#include "common/estimators/direct_light.h"
#include "common/estimators/precomputed_irradiance.h"
#include "common/estimators/radiance_estimate.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon_maps.h"
#include "common/render/integrator.h"
#include "common/render/irradiance_cache.h"
#include "common/render/radiance_part.h"
#include "common/sampling/sample_layout.h"

namespace pf {

enum class DirectLightMode { kNone, kMonteCarlo, kPhotonDirect };
enum class LocalPassLookup { kFull, kPrecomputed };

struct PhotonMapIntegratorOptions {
  RadianceEstimateOptions global;   // k nearest, unbounded radius by default
  RadianceEstimateOptions caustic;  // max radius + threshold (§4.1), see DefaultCausticOptions
  // The separate direct map read as photons (local pass hits, an estimated glossy lobe with
  // separate direct light): bounded, see DefaultDirectPhotonOptions.
  RadianceEstimateOptions direct_photons;
  int glossy_depth = 1;  // glossy bounces followed before using the estimate
  int max_depth = 32;    // singular-chain cap (Russian roulette ends most earlier)
  DirectLightMode direct = DirectLightMode::kNone;
  DirectLightOptions monte_carlo;     // §4.2.1
  PhotonDirectOptions photon_direct;  // §4.2.3
  int local_pass_rays = 0;            // N_lp (§4.3); 0 = off
  // What a local-pass gather ray reads at its hit: the full photon-map estimate, or the
  // precomputed irradiance of the nearest site (Christensen 1999; precomputed_irradiance.h),
  // built once per map on first use.
  LocalPassLookup local_pass_lookup = LocalPassLookup::kFull;
  PrecomputedIrradianceOptions precomputed;
  // Irradiance caching of the local pass (irradiance_cache.h; error = Ward's a, 0 = off): at a
  // first estimated surface whose diffuse part is Lambertian reflection, the gather is replaced
  // by the block's cached irradiance where a record is close enough; a new gather (N_lp rays)
  // otherwise, which becomes a record. Only through RenderPixels (LiInBlock): Li alone gathers.
  IrradianceCacheOptions irradiance_cache;
  // Radius hint (PhotonMap::QueryWithHint) for the estimates at a camera path's surfaces: the
  // previous sample of the same pixel's k-th distance × kPixelRadiusHintScale. Exact (the same
  // photons); off only to measure it (bench/radius_hint_bench).
  bool pixel_radius_hint = true;
  // Which part of the radiance Li returns (radiance_part.h). kUnmapped never reads the maps
  // unless direct light is PhotonDirect (its light choice reads the direct photons).
  RadiancePart part = RadiancePart::kAll;
};

inline constexpr float kPixelRadiusHintScale = 1.2f;

// Caustic estimate defaults: the same k, a maximum radius of 1 % of the scene's bounding-box
// diagonal, and the thesis's threshold of 10 % of k photons (§4.1).
RadianceEstimateOptions DefaultCausticOptions(int k, const Bounds3& scene_bounds);

// Direct-photon estimate defaults: the global options with a maximum radius of 5 % of the
// scene's bounding-box diagonal. Direct photons are absent wherever the lights do not shine
// (a ceiling lit from below); an unbounded query filtered by the direction test then visits
// every direct photon before giving up — measured on Cornell with the local pass: 150x slower.
inline constexpr float kDirectPhotonRadiusFraction = 0.05f;
RadianceEstimateOptions DefaultDirectPhotonOptions(const RadianceEstimateOptions& global,
                                                   const Bounds3& scene_bounds);

// What the photon maps of a given integrator configuration must contain.
void ConfigureMapsFor(const PhotonMapIntegratorOptions& options, PhotonMapsOptions* maps);
// Whether an estimator of `options` reads the separate direct map: PhotonDirect (§4.2.3), or the
// local pass's gather hits (§4.3, precomputed irradiance included) next to separate direct light.
bool DirectMapRead(const PhotonMapIntegratorOptions& options);

class PhotonMapIntegrator final : public Integrator {
 public:
  // `maps` must have been built with ConfigureMapsFor(options, ...). `lights` may be null only
  // when direct == kNone.
  PhotonMapIntegrator(const EmbreeScene& scene, const LightSampler* lights, const PhotonMaps& maps,
                      PhotonMapIntegratorOptions options);
  PhotonMapIntegrator(const EmbreeScene& scene, const PhotonMaps& maps, PhotonMapIntegratorOptions options)
      : PhotonMapIntegrator(scene, nullptr, maps, options) {}
  ~PhotonMapIntegrator() override;
  Rgb Li(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters) const override;
  std::unique_ptr<PixelBlockState> NewPixelBlockState() const override;
  Rgb LiInBlock(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters,
                PixelBlockState& block) const override;
  // The emission part of the radiance only (radiance_part.h: not for kMapped).
  bool SplitsPrimaryEmission() const override;
  Rgb PrimaryEmission(const Ray& camera_ray, TraceCounters& counters, bool* surface_emitter) const override;
  const char* name() const override { return "photonmap"; }

 private:
  // Photon-map radiance leaving x towards wo through `lobes`: global (+ direct map when
  // `include_direct_photons`) + caustic.
  // `camera_path`: x is a surface of the camera path (not a gather hit), whose global and
  // caustic queries take the radius hint of the pixel's previous sample.
  Rgb MapRadiance(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes,
                  bool include_direct_photons, TraceCounters& counters, bool camera_path = false) const;
  Rgb DirectLight(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes, Sampler& sampler,
                  const PathVertexSlots& slots, TraceCounters& counters) const;
  // The light of every punctual light on `lobes` (glossy lobes the path follows): a followed ray
  // finds area emitters and the environment by hitting them, a delta light never. Deterministic
  // (no sample drawn): each light's contribution, summed.
  Rgb DeltaLightsOnFollowedLobes(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes,
                                 TraceCounters& counters) const;
  Rgb Trace(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters, IrradianceCache* cache) const;
  // The local pass at x: the cache's interpolation or a new record when `cache` is given and
  // x's diffuse part is Lambertian reflection, GatherRays otherwise.
  Rgb Gather(const Bsdf& bsdf, const Material& material, const SurfaceHit& hit, const Vec3& wo,
             uint32_t lobes, Sampler& sampler, const PathVertexSlots& slots, TraceCounters& counters,
             IrradianceCache* cache) const;
  // Mean of weight·L(y) over the N_lp gather rays sampled from `bsdf`'s diffuse lobes in `lobes`;
  // adds Σ 1/distance and the number of hits (for the cache's R_i) when asked.
  Rgb GatherRays(const Bsdf& bsdf, const SurfaceHit& hit, const Vec3& wo, uint32_t lobes, Sampler& sampler,
                 const PathVertexSlots& slots, TraceCounters& counters, double* inverse_distance_sum,
                 int* hits) const;
  // The diffuse radiance leaving a gather hit y towards wo (local_pass_lookup).
  Rgb GatherHitRadiance(const Bsdf& by, const Material& my, const SurfaceHit& y, const Vec3& wo,
                        TraceCounters& counters) const;
  // Builds or reuses (maps_.derived) the precomputed irradiance.
  void PreparePrecomputedIrradiance();

  const EmbreeScene& scene_;
  const LightSampler* lights_;
  const PhotonMaps& maps_;
  PhotonMapIntegratorOptions options_;
  std::unique_ptr<MonteCarloDirectLight> monte_carlo_;
  std::unique_ptr<PhotonDirectLight> photon_direct_;
  std::shared_ptr<const PrecomputedIrradiance> precomputed_;
};

}  // namespace pf
