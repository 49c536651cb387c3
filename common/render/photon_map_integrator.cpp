#include "common/render/photon_map_integrator.h"

#include "common/materials/bsdf.h"

namespace pf {

RadianceEstimateOptions DefaultCausticOptions(int k, const Bounds3& scene_bounds) {
  RadianceEstimateOptions o;
  o.k = k;
  o.max_radius = std::max(0.01f * Length(scene_bounds.Diagonal()), 1e-12f);
  o.min_fraction = 0.1f;
  return o;
}

PhotonMapIntegrator::PhotonMapIntegrator(const EmbreeScene& scene, const PhotonMaps& maps,
                                         PhotonMapIntegratorOptions options)
    : scene_(scene), maps_(maps), options_(options) {}

Rgb PhotonMapIntegrator::Li(const Ray& camera_ray, Rng& rng, TraceCounters& counters) const {
  // Per-thread query scratch, reused across queries (NearestPhotons allocates only at first).
  thread_local NearestPhotons nearest;
  const SceneDescription& desc = scene_.description();
  constexpr uint32_t kDiffuseLobes = kLobeDiffuseReflection | kLobeDiffuseTransmission;
  constexpr uint32_t kSingularLobes = kLobeGlossyReflection | kLobeSpecularReflection | kLobeSpecularTransmission;

  Rgb radiance(0.0f), throughput(1.0f);
  Ray ray = camera_ray;
  int glossy_bounces = 0;
  for (int depth = 0; depth < options_.max_depth; ++depth) {
    ++counters.rays;
    const std::optional<SurfaceHit> hit = scene_.Intersect(ray);
    if (!hit) break;
    const Material& material = desc.materials[hit->material];
    // Every path reaching here came from the camera through singular bounces only, so
    // emission is never counted twice (diffuse bounces end the path in an estimate).
    if (material.IsEmissive() && hit->front_face) radiance += throughput * material.emission;

    const Bsdf bsdf(material, hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;
    const bool follow_glossy = glossy_bounces < options_.glossy_depth;
    const uint32_t estimated = kDiffuseLobes | (follow_glossy ? 0u : uint32_t(kLobeGlossyReflection));
    const uint32_t followed = kSingularLobes & ~estimated;

    if (bsdf.HasLobes(estimated)) {
      radiance += throughput *
                  EstimateRadiance(*maps_.global, bsdf, hit->position, wo, estimated, options_.global, nearest).radiance;
      if (maps_.caustic)
        radiance += throughput * EstimateRadiance(*maps_.caustic, bsdf, hit->position, wo, estimated,
                                                  options_.caustic, nearest)
                                     .radiance;
    }
    if (!bsdf.HasLobes(followed)) break;
    const float ul = rng.Uniform(), u1 = rng.Uniform(), u2 = rng.Uniform();
    const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u1, u2, Bsdf::Mode::kNormalized, followed);
    if (!s || s->weight.IsBlack()) break;
    throughput *= s->weight;
    if (s->lobe & kLobeGlossyReflection) ++glossy_bounces;
    ray = Ray{scene_.SpawnOrigin(*hit, s->wi), s->wi};
    if (depth >= 4) {  // Russian roulette on long singular chains (e.g. glass inside glass)
      const float survive = std::min(1.0f, throughput.Max());
      if (!(survive > 0.0f) || rng.Uniform() >= survive) break;
      throughput *= 1.0f / survive;
    }
  }
  return radiance;
}

}  // namespace pf
