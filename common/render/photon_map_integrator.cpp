#include "common/render/photon_map_integrator.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>

#include "common/core/error.h"
#include "common/estimators/direct_light.h"
#include "common/materials/bsdf.h"
#include "common/scene/surface_material.h"

namespace pf {
namespace {

constexpr uint32_t kDiffuseLobes = kLobeDiffuseReflection | kLobeDiffuseTransmission;
constexpr uint32_t kSingularLobes =
    kLobeGlossyReflection | kLobeSpecularReflection | kLobeSpecularTransmission | kLobeGlossyTransmission;

// Per-thread query scratch, reused across queries (NearestPhotons allocates only at first).
NearestPhotons& Scratch() {
  thread_local NearestPhotons nearest;
  return nearest;
}

// The k-th distance² of the last camera-path estimate of the pixel being rendered on this
// thread, per map (global, caustic). Reset when the render driver moves to another pixel
// (t_pixel_epoch): a hint from another pixel would make the heap order — the last bits of a
// sum — depend on which pixels a thread rendered before.
struct PixelRadii {
  uint64_t epoch = ~uint64_t(0);
  float radius2[2] = {0.0f, 0.0f};
};
PixelRadii& ThisPixelRadii() {
  thread_local PixelRadii radii;
  if (radii.epoch != t_pixel_epoch) radii = PixelRadii{t_pixel_epoch, {0.0f, 0.0f}};
  return radii;
}

}  // namespace

RadianceEstimateOptions DefaultCausticOptions(int k, const Bounds3& scene_bounds) {
  RadianceEstimateOptions o;
  o.k = k;
  o.max_radius = std::max(0.01f * Length(scene_bounds.Diagonal()), 1e-12f);
  o.min_fraction = 0.1f;
  return o;
}

RadianceEstimateOptions DefaultDirectPhotonOptions(const RadianceEstimateOptions& global,
                                                   const Bounds3& scene_bounds) {
  RadianceEstimateOptions o = global;
  o.max_radius =
      std::min(o.max_radius, std::max(kDirectPhotonRadiusFraction * Length(scene_bounds.Diagonal()), 1e-12f));
  return o;
}

bool DirectMapRead(const PhotonMapIntegratorOptions& options) {
  return options.direct == DirectLightMode::kPhotonDirect ||
         (options.direct != DirectLightMode::kNone && options.local_pass_rays > 0);
}

void ConfigureMapsFor(const PhotonMapIntegratorOptions& options, PhotonMapsOptions* maps) {
  maps->separate_direct = options.direct != DirectLightMode::kNone;
  maps->direct_map = DirectMapRead(options);
  maps->keep_light_ids = options.direct == DirectLightMode::kPhotonDirect;
  // Origins also for the precomputed irradiance's sites when they are estimated with the
  // occlusion test (PreparePrecomputedIrradiance).
  maps->keep_origins =
      options.global.occlusion_test || options.caustic.occlusion_test ||
      (options.local_pass_rays > 0 && options.local_pass_lookup == LocalPassLookup::kPrecomputed &&
       options.precomputed.occlusion_test);
}

PhotonMapIntegrator::PhotonMapIntegrator(const EmbreeScene& scene, const LightSampler* lights,
                                         const PhotonMaps& maps, PhotonMapIntegratorOptions options)
    : scene_(scene), lights_(lights), maps_(maps), options_(options) {
  if (options.direct != DirectLightMode::kNone && !lights)
    throw InputError("direct light: a light sampler is required");
  // An emission + direct light task (RadiancePart::kUnmapped, radiance_part.h) reads no direct
  // map unless PhotonDirect chooses its lights from it: the local pass that makes
  // DirectMapRead true belongs to the mapped part, and such a task gets empty maps.
  const bool reads_direct_map = DirectMapRead(options) && (options.part != RadiancePart::kUnmapped ||
                                                           options.direct == DirectLightMode::kPhotonDirect);
  if (reads_direct_map && !maps.direct)
    throw InputError("direct light: the photon maps were built without a separate direct map");
  if (options.direct == DirectLightMode::kMonteCarlo)
    monte_carlo_ = std::make_unique<MonteCarloDirectLight>(scene, *lights, options.monte_carlo);
  if (options.direct == DirectLightMode::kPhotonDirect) {
    if (maps.direct_attributes.light.size() != maps.direct->size())
      throw InputError("PhotonDirect: the direct photons carry no light ids (keep_light_ids)");
    photon_direct_ = std::make_unique<PhotonDirectLight>(scene, *lights, *maps.direct,
                                                         maps.direct_attributes.light, options.photon_direct);
  }
  if (options_.local_pass_rays > 0 && options_.local_pass_lookup == LocalPassLookup::kPrecomputed &&
      options_.part != RadiancePart::kUnmapped)
    PreparePrecomputedIrradiance();
  IrradianceCacheOptions& ic = options_.irradiance_cache;
  if (ic.error < 0.0f || !std::isfinite(ic.error)) throw InputError("irradiance cache: error must be >= 0");
  const float diagonal = std::max(Length(scene.bounds().Diagonal()), 1e-12f);
  if (ic.min_radius <= 0.0f) ic.min_radius = kIrradianceCacheMinRadiusFraction * diagonal;
  if (ic.max_radius <= 0.0f) ic.max_radius = kIrradianceCacheMaxRadiusFraction * diagonal;
}

std::unique_ptr<PixelBlockState> PhotonMapIntegrator::NewPixelBlockState() const {
  if (options_.local_pass_rays <= 0 || options_.irradiance_cache.error <= 0.0f) return nullptr;
  return std::make_unique<IrradianceCacheBlock>(options_.irradiance_cache);
}

PhotonMapIntegrator::~PhotonMapIntegrator() = default;

void PhotonMapIntegrator::PreparePrecomputedIrradiance() {
  // Everything the sites' estimates depend on (besides the maps themselves).
  auto describe = [](const RadianceEstimateOptions& o) {
    return std::to_string(o.k) + "," + std::to_string(o.max_radius) + "," +
           std::to_string(int(o.direction_test)) + "," + std::to_string(o.min_fraction) + "," +
           std::to_string(o.exclude_boundary_photon) + "," + std::to_string(o.occlusion_test) + "," +
           std::to_string(o.adaptive_k_min);
  };
  const PrecomputedIrradianceOptions& p = options_.precomputed;
  const std::string key = "precomputed-irradiance|" + describe(options_.global) + "|" +
                          describe(options_.direct_photons) + "|" + describe(options_.caustic) + "|" +
                          std::to_string(p.stride) + "," + std::to_string(p.normal_cos) + "," +
                          std::to_string(p.max_radius_fraction) + "," + std::to_string(p.candidates) + "," +
                          std::to_string(p.average) + "," + std::to_string(p.occlusion_test);
  PhotonMaps::Derived& slot = *maps_.derived;
  std::lock_guard lock(slot.mutex);
  if (slot.key == key && slot.value) {
    precomputed_ = std::static_pointer_cast<const PrecomputedIrradiance>(slot.value);
    return;
  }
  // With p.occlusion_test the sites' estimates drop photons whose incoming path x cannot see (Wald
  // 1999, §4.1.1), whatever the camera path does: a site is estimated once and read by many
  // gather rays, so its k shadow rays are paid once per map, and without the test the sites next
  // to a wall carry the light of the room behind it into every gather that reads them
  // (precomputed_irradiance.h; docs/results/kernel.md §2).
  RadianceEstimateOptions global = options_.global, direct = options_.direct_photons,
                          caustic = options_.caustic;
  if (p.occlusion_test) global.occlusion_test = direct.occlusion_test = caustic.occlusion_test = true;
  precomputed_ = PrecomputedIrradiance::Build(
      scene_, maps_, p, [this, global, direct, caustic](const Bsdf& white, const Vec3& x, const Vec3& n) {
        NearestPhotons& nearest = Scratch();
        auto estimate = [&](const PhotonMap& map, const PhotonAttributes& attributes,
                            const RadianceEstimateOptions& o) {
          const EstimateContext context{attributes.origin.empty() ? nullptr : &attributes.origin, &scene_};
          return EstimateRadiance(map, white, x, n, kLobeDiffuseReflection, o, nearest, context).radiance;
        };
        Rgb L = estimate(*maps_.global, maps_.global_attributes, global);
        if (maps_.direct) L += estimate(*maps_.direct, maps_.direct_attributes, direct);
        if (maps_.caustic) L += estimate(*maps_.caustic, maps_.caustic_attributes, caustic);
        return L;
      });
  slot.key = key;
  slot.value = precomputed_;
}

Rgb PhotonMapIntegrator::GatherHitRadiance(const Bsdf& by, const Material& my, const SurfaceHit& y,
                                           const Vec3& wo, TraceCounters& counters) const {
  if (!by.HasLobes(kDiffuseLobes)) return Rgb(0.0f);
  // Christensen 1999: L(y) = ρd/π · E(nearest site) on y's side facing the gather ray. Diffuse
  // transmitters see light from both sides: they keep the full estimate.
  if (precomputed_ && my.diffuse_transmittance.IsBlack()) {
    const Vec3 ng = Dot(wo, y.geometric_normal) >= 0.0f ? y.geometric_normal : -y.geometric_normal;
    const Vec3 ns = Dot(y.shading_normal, ng) >= 0.0f ? y.shading_normal : -y.shading_normal;
    if (const std::optional<Rgb> e = precomputed_->Lookup(y.position, ns, Scratch()))
      return my.diffuse_reflectance * (*e * kInvPi);
  }
  return MapRadiance(by, y.position, wo, kDiffuseLobes, /*include_direct_photons=*/true, counters);
}

Rgb PhotonMapIntegrator::MapRadiance(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes,
                                     bool include_direct_photons, TraceCounters& counters,
                                     bool camera_path) const {
  NearestPhotons& nearest = Scratch();
  PixelRadii* radii = camera_path && options_.pixel_radius_hint ? &ThisPixelRadii() : nullptr;
  auto estimate = [&](const PhotonMap& map, const PhotonAttributes& attributes,
                      const RadianceEstimateOptions& o, int hint_slot) {
    EstimateContext context{attributes.origin.empty() ? nullptr : &attributes.origin, &scene_};
    if (radii && hint_slot >= 0 && radii->radius2[hint_slot] > 0.0f)
      context.radius_hint = kPixelRadiusHintScale * std::sqrt(radii->radius2[hint_slot]);
    const RadianceEstimateResult r = EstimateRadiance(map, bsdf, x, wo, lobes, o, nearest, context);
    if (radii && hint_slot >= 0) radii->radius2[hint_slot] = r.photons_used > 0 ? r.radius2 : 0.0f;
    counters.shadow_rays += uint64_t(r.shadow_rays);
    return r.radiance;
  };
  Rgb L = estimate(*maps_.global, maps_.global_attributes, options_.global, 0);
  if (include_direct_photons && maps_.direct)
    L += estimate(*maps_.direct, maps_.direct_attributes, options_.direct_photons, -1);
  if (maps_.caustic) L += estimate(*maps_.caustic, maps_.caustic_attributes, options_.caustic, 1);
  return L;
}

Rgb PhotonMapIntegrator::DirectLight(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes,
                                     Sampler& sampler, const PathVertexSlots& slots,
                                     TraceCounters& counters) const {
  if (monte_carlo_) return monte_carlo_->Estimate(bsdf, x, wo, lobes, sampler, slots, counters);
  if (photon_direct_)
    return photon_direct_->Estimate(bsdf, x, wo, lobes, sampler, slots, counters, Scratch());
  return Rgb(0.0f);
}

Rgb PhotonMapIntegrator::DeltaLightsOnFollowedLobes(const Bsdf& bsdf, const Vec3& x, const Vec3& wo,
                                                    uint32_t lobes, TraceCounters& counters) const {
  if (!lights_ || lights_->punctual().empty() || !bsdf.HasLobes(lobes)) return Rgb(0.0f);
  Rgb sum(0.0f);
  // Each punctual light by its own index: the lights are not numbered from the punctual ones to the
  // end (an environment comes after them; light_sampler.h). pdf_area is 1.
  for (size_t i = 0; i < lights_->punctual().size(); ++i)
    sum += DeltaLightContribution(*lights_, lights_->PunctualSample(i), bsdf, x, wo, lobes, counters);
  return sum;
}

Rgb PhotonMapIntegrator::GatherRays(const Bsdf& bsdf, const SurfaceHit& hit, const Vec3& wo, uint32_t lobes,
                                    Sampler& sampler, const PathVertexSlots& slots, TraceCounters& counters,
                                    double* inverse_distance_sum, int* hits) const {
  const SceneDescription& desc = scene_.description();
  const bool separate_direct = options_.direct != DirectLightMode::kNone;
  const int n = options_.local_pass_rays;
  ++counters.gathers;
  Rgb sum(0.0f);
  for (int j = 0; j < n; ++j) {
    const float ul = sampler.Get1D(slots.gather_lobe, uint32_t(j), uint32_t(n));
    const Sample2 u = sampler.Get2D(slots.gather_dir, uint32_t(j), uint32_t(n));
    const std::optional<BsdfSample> s =
        bsdf.Sample(wo, ul, u.u, u.v, Bsdf::Mode::kNormalized, lobes & kDiffuseLobes);
    if (!s || s->weight.IsBlack()) continue;
    ++counters.rays;
    const std::optional<SurfaceHit> y = scene_.Intersect(Ray{scene_.SpawnOrigin(hit, s->wi), s->wi});
    if (!y) {
      // The environment is an emitter seen by the gather ray, counted like a hit emitter's Le.
      if (!separate_direct && desc.environment) sum += s->weight * desc.environment->Radiance(s->wi);
      continue;
    }
    if (inverse_distance_sum && y->t > 0.0f) {
      *inverse_distance_sum += 1.0 / double(y->t);
      ++*hits;
    }
    std::optional<Material> textured;  // filled only for a textured material
    const Material& my = MaterialAt(desc, y->material, y->uv, &textured);
    Rgb Ly(0.0f);
    if (!separate_direct && my.IsEmissive() && y->front_face) Ly += my.emission;
    const Bsdf by(my, y->shading_normal, y->geometric_normal);
    Ly += GatherHitRadiance(by, my, *y, -s->wi, counters);
    sum += s->weight * Ly;
  }
  // Sampling only the diffuse lobes makes each weight f_d·cos/pdf over exactly those lobes.
  return sum * (1.0f / float(n));
}

Rgb PhotonMapIntegrator::Gather(const Bsdf& bsdf, const Material& material, const SurfaceHit& hit,
                                const Vec3& wo, uint32_t lobes, Sampler& sampler,
                                const PathVertexSlots& slots, TraceCounters& counters,
                                IrradianceCache* cache) const {
  if (!cache || !material.diffuse_transmittance.IsBlack())
    return GatherRays(bsdf, hit, wo, lobes, sampler, slots, counters, nullptr, nullptr);
  // The diffuse part is ρd/π · E (Lambertian reflection): cache E/π, independent of ρd, on the
  // side of the surface the gather rays leave (the lobe normal of bsdf.h).
  const Vec3 ng = Dot(wo, hit.geometric_normal) >= 0.0f ? hit.geometric_normal : -hit.geometric_normal;
  const Vec3 ns = Dot(hit.shading_normal, ng) >= 0.0f ? hit.shading_normal : -hit.shading_normal;
  if (const std::optional<Rgb> e = cache->Interpolate(hit.position, ns)) {
    ++counters.cache_interpolations;
    return material.diffuse_reflectance * *e;
  }
  Material white;
  white.diffuse_reflectance = Rgb(1.0f);
  const Bsdf white_bsdf(white, hit.shading_normal, hit.geometric_normal);
  double inverse_distance_sum = 0.0;
  int hits = 0;
  const Rgb e = GatherRays(white_bsdf, hit, wo, kLobeDiffuseReflection, sampler, slots, counters,
                           &inverse_distance_sum, &hits);
  cache->Add(hit.position, ns, e, inverse_distance_sum, hits);
  return material.diffuse_reflectance * e;
}

Rgb PhotonMapIntegrator::Li(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters) const {
  return Trace(camera_ray, sampler, counters, nullptr);
}

Rgb PhotonMapIntegrator::LiInBlock(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters,
                                   PixelBlockState& block) const {
  return Trace(camera_ray, sampler, counters, &static_cast<IrradianceCacheBlock&>(block).cache);
}

bool PhotonMapIntegrator::SplitsPrimaryEmission() const {
  // Without an emitting surface no pixel's lattice could see one: nothing to pay for. A textured
  // emission is the material's emission times the texel, so a black one never emits.
  const std::vector<Material>& materials = scene_.description().materials;
  return options_.part != RadiancePart::kMapped && options_.max_depth > 0 &&
         std::any_of(materials.begin(), materials.end(), [](const Material& m) { return m.IsEmissive(); });
}

// Trace's first vertex, emission only: the same test and the same material lookup.
Rgb PhotonMapIntegrator::PrimaryEmission(const Ray& camera_ray, TraceCounters& counters,
                                         bool* surface_emitter) const {
  *surface_emitter = false;
  const SceneDescription& desc = scene_.description();
  ++counters.rays;
  const std::optional<SurfaceHit> hit = scene_.Intersect(camera_ray);
  if (!hit) return desc.environment ? desc.environment->Radiance(camera_ray.direction) : Rgb(0.0f);
  std::optional<Material> textured;
  const Material& material = MaterialAt(desc, hit->material, hit->uv, &textured);
  if (!material.IsEmissive() || !hit->front_face) return Rgb(0.0f);
  *surface_emitter = true;
  return material.emission;
}

Rgb PhotonMapIntegrator::Trace(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters,
                               IrradianceCache* cache) const {
  const SceneDescription& desc = scene_.description();
  const bool separate_direct = options_.direct != DirectLightMode::kNone;
  // radiance_part.h: the map part and the rest follow the same singular chain (each with its own
  // random choices when rendered apart), so each is an unbiased estimate of its share.
  const bool unmapped_part = options_.part != RadiancePart::kMapped;
  const bool mapped_part = options_.part != RadiancePart::kUnmapped;

  Rgb radiance(0.0f), throughput(1.0f);
  Ray ray = camera_ray;
  int glossy_bounces = 0;
  bool gathered = false;  // the local pass runs at the first estimated surface only
  for (int depth = 0; depth < options_.max_depth; ++depth) {
    ++counters.rays;
    const std::optional<SurfaceHit> hit = scene_.Intersect(ray);
    if (!hit) {
      // The environment, seen like an emitter below: this path is camera + singular bounces only.
      if (unmapped_part && desc.environment)
        radiance += throughput * desc.environment->Radiance(ray.direction);
      break;
    }
    std::optional<Material> textured;  // filled only for a textured material
    const Material& material = MaterialAt(desc, hit->material, hit->uv, &textured);
    const PathVertexSlots slots = SlotsOfVertex(depth);
    // Every path reaching here came from the camera through singular bounces only, so
    // emission (and the environment's, above) is never counted twice (diffuse bounces end the path in an
    // estimate).
    if (unmapped_part && material.IsEmissive() && hit->front_face) radiance += throughput * material.emission;

    const Bsdf bsdf(material, hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;
    const bool follow_glossy = glossy_bounces < options_.glossy_depth;
    const uint32_t estimated = kDiffuseLobes | (follow_glossy ? 0u : uint32_t(kLobeGlossyReflection));
    const uint32_t followed = kSingularLobes & ~estimated;

    if (bsdf.HasLobes(estimated)) {
      Rgb L(0.0f);
      if (separate_direct && unmapped_part)
        L += DirectLight(bsdf, hit->position, wo, estimated, sampler, slots, counters);
      if (!mapped_part) {
        // Only emission and direct light: no estimate, no gather.
      } else if (options_.local_pass_rays > 0 && !gathered && bsdf.HasLobes(kDiffuseLobes)) {
        gathered = true;
        L += Gather(bsdf, material, *hit, wo, estimated, sampler, slots, counters, cache);
        // Caustics through the diffuse lobes still come from the caustic map; a glossy lobe
        // estimated from the maps reads all of them (caustic map included) below.
        if (maps_.caustic) {
          NearestPhotons& nearest = Scratch();
          const EstimateContext context{
              maps_.caustic_attributes.origin.empty() ? nullptr : &maps_.caustic_attributes.origin, &scene_};
          L += EstimateRadiance(*maps_.caustic, bsdf, hit->position, wo, estimated & kDiffuseLobes,
                                options_.caustic, nearest, context)
                   .radiance;
        }
        if (estimated & kLobeGlossyReflection)
          L += MapRadiance(bsdf, hit->position, wo, kLobeGlossyReflection, !separate_direct, counters);
      } else {
        L += MapRadiance(bsdf, hit->position, wo, estimated, /*include_direct_photons=*/false, counters,
                         /*camera_path=*/true);
      }
      radiance += throughput * L;
    }
    // A followed glossy lobe sees the punctual lights only through this: its rays cannot hit them.
    const uint32_t followed_glossy = followed & (kLobeGlossyReflection | kLobeGlossyTransmission);
    if (unmapped_part && followed_glossy)
      radiance += throughput * DeltaLightsOnFollowedLobes(bsdf, hit->position, wo, followed_glossy, counters);
    if (!bsdf.HasLobes(followed)) break;
    const float ul = sampler.Get1D(slots.bsdf_lobe);
    const Sample2 u = sampler.Get2D(slots.bsdf_dir);
    const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u.u, u.v, Bsdf::Mode::kNormalized, followed);
    if (!s || s->weight.IsBlack()) break;
    throughput *= s->weight;
    if (s->lobe & kLobeGlossyReflection) ++glossy_bounces;
    ray = Ray{scene_.SpawnOrigin(*hit, s->wi), s->wi};
    if (depth >= 4) {  // Russian roulette on long singular chains (e.g. glass inside glass)
      const float survive = std::min(1.0f, throughput.Max());
      if (!(survive > 0.0f) || sampler.Get1D(slots.roulette) >= survive) break;
      throughput *= 1.0f / survive;
    }
  }
  return radiance;
}

}  // namespace pf
