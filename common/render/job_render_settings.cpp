#include "common/render/job_render_settings.h"

#include <stdexcept>

#include "common/photon/photon_tracer.h"

namespace pf {

SceneTraits TraitsOf(const SceneDescription& scene) {
  return SceneTraits{.caustic_paths = SceneNeedsCausticMap(scene), .lights = int(scene.num_lights)};
}

JobRenderSettings JobRenderSettings::Resolved(const SceneDescription& scene,
                                              std::vector<AutoChoice>* choices) const {
  return Resolved(TraitsOf(scene), choices);
}

JobRenderSettings JobRenderSettings::Resolved(const SceneTraits& scene,
                                              std::vector<AutoChoice>* choices) const {
  JobRenderSettings r = *this;
  auto choose = [&](const char* setting, const char* value, std::string reason) {
    if (choices) choices->push_back({setting, value, std::move(reason)});
  };
  if (r.integrator != IntegratorKind::kPhotonMap) return r;
  if (r.caustic == CausticMapMode::kAuto) {
    const bool need = scene.caustic_paths;
    r.caustic = need ? CausticMapMode::kOn : CausticMapMode::kOff;
    choose("caustic-map", need ? "on" : "off",
           need
               ? "the scene has specular or glossy surfaces (caustic paths L S+ D exist)"
               : "no specular or glossy surface: no caustic path can exist (a caustic map would stay empty)");
  }
  if (!r.direct) {
    // Wald 1999, §4.2.3: with many lights, Monte Carlo spends most shadow rays on lights that
    // do not reach the point; the direct photons tell which lights matter (PhotonDirect).
    // With few lights, stratified MC shadow rays are cheaper and have no photon-map bias.
    const int lights = scene.lights;
    if (lights >= kPhotonDirectMinLights) {
      r.direct = DirectLightMode::kPhotonDirect;
      choose("direct", "photon-direct",
             std::to_string(lights) + " lights (>= " + std::to_string(kPhotonDirectMinLights) +
                 "): shadow rays go to the lights whose direct photons reach the point (4.2.3)");
    } else {
      r.direct = DirectLightMode::kMonteCarlo;
      choose("direct", "monte-carlo",
             std::to_string(lights) + (lights == 1 ? " light" : " lights") + " (< " +
                 std::to_string(kPhotonDirectMinLights) +
                 "): stratified shadow rays per light, sharp shadows, no direct photons in the estimate "
                 "(4.2.1)");
    }
  }
  return r;
}

PhotonMapIntegratorOptions JobRenderSettings::IntegratorOptions(const Bounds3& bounds) const {
  if (!direct)
    throw std::logic_error(
        "JobRenderSettings::IntegratorOptions: direct light is still 'auto' (call Resolved)");
  PhotonMapIntegratorOptions io;
  io.global.k = k;
  io.global.direction_test = direction_test;
  io.global.occlusion_test = occlusion_test;
  io.global.adaptive_k_min = adaptive_k_min;
  io.direct_photons = DefaultDirectPhotonOptions(io.global, bounds);
  io.caustic = DefaultCausticOptions(k, bounds);
  if (caustic_radius > 0.0f) io.caustic.max_radius = caustic_radius;
  io.caustic.direction_test = direction_test;
  io.caustic.occlusion_test = occlusion_test;
  io.caustic.adaptive_k_min = adaptive_k_min;
  io.glossy_depth = glossy_depth;
  io.direct = *direct;
  io.monte_carlo.shadow_rays = shadow_rays;
  io.monte_carlo.uniform_fraction = light_uniform_fraction;
  io.photon_direct.k = photon_direct_k;
  io.photon_direct.samples = shadow_rays;
  io.photon_direct.non_contributing = non_contributing;
  io.photon_direct.cache_radius_fraction = photon_direct_cache;
  io.photon_direct.max_radius = io.direct_photons.max_radius;  // same bound, same reason (direct_light.h)
  io.local_pass_rays = local_pass_rays;
  io.local_pass_lookup = local_pass_lookup;
  io.precomputed.occlusion_test = site_occlusion_test;
  io.irradiance_cache.error = irradiance_cache_error;
  return io;
}

PhotonMapsOptions JobRenderSettings::MapsOptions() const {
  PhotonMapsOptions mo;
  mo.tracing.photons = photons;
  mo.tracing.sampler = sampler;
  mo.tracing.caustic_split = caustic_split;
  mo.tracing.caustic_split_method = caustic_split_method;
  mo.kind = structure;
  mo.structure.kd_split_rule = kd_split;
  mo.structure.grid.expected_k = k;
  mo.caustic = caustic;
  ConfigureMapsFor(IntegratorOptions(Bounds3()), &mo);
  mo.importance.mode = importance;
  mo.importance.min_probability = importance_min_probability;
  mo.importance.strength = importance_strength;
  mo.importance.importons = importons;
  // The local pass reads the map at its gather rays' hits, one diffuse bounce from the visible
  // points: the importons go one bounce further so that those hits count as important (§4.3).
  mo.importance.diffuse_bounces = local_pass_rays > 0 ? 1 : 0;
  return mo;
}

}  // namespace pf
