#include "common/estimators/direct_light.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pf {

Rgb DeltaLightContribution(const LightSampler& lights, const LightSample& ls, const Bsdf& bsdf, const Vec3& x,
                           const Vec3& wo, uint32_t lobes, TraceCounters& counters) {
  const DeltaIncidence in = lights.Incidence(ls, x);
  if (in.irradiance.IsBlack()) return Rgb(0.0f);  // outside a spot's cone
  const Rgb f = bsdf.EvalLobes(wo, in.wi, lobes);
  if (f.IsBlack()) return Rgb(0.0f);
  ++counters.shadow_rays;
  if (!lights.Unoccluded(x, bsdf.geometric_normal(), in)) return Rgb(0.0f);
  return f * in.irradiance * (std::fabs(Dot(in.wi, bsdf.shading_normal())) / ls.pdf_area);
}

Rgb EnvironmentLightContribution(const LightSampler& lights, const LightSample& ls, const Bsdf& bsdf,
                                 const Vec3& x, const Vec3& wo, uint32_t lobes, TraceCounters& counters) {
  const float pdf = ls.pdf_area * ls.pdf_direction;
  if (!(pdf > 0.0f) || ls.radiance.IsBlack()) return Rgb(0.0f);
  const Rgb f = bsdf.EvalLobes(wo, ls.wi, lobes);
  if (f.IsBlack()) return Rgb(0.0f);
  ++counters.shadow_rays;
  if (!lights.UnoccludedTowards(x, bsdf.geometric_normal(), ls.wi)) return Rgb(0.0f);
  return f * ls.radiance * (std::fabs(Dot(ls.wi, bsdf.shading_normal())) / pdf);
}

Rgb SampleOneLight(const EmbreeScene& scene, const LightSampler& lights, size_t light, const Bsdf& bsdf,
                   const Vec3& x, const Vec3& wo, uint32_t lobes, float u_select, Sample2 u,
                   TraceCounters& counters) {
  const LightSample ls = lights.SampleLight(light, u_select, u.u, u.v);
  if (ls.delta()) return DeltaLightContribution(lights, ls, bsdf, x, wo, lobes, counters);
  if (ls.environment) return EnvironmentLightContribution(lights, ls, bsdf, x, wo, lobes, counters);
  const Vec3 to_light = ls.position - x;
  const float dist2 = LengthSquared(to_light);
  if (!(dist2 > 0.0f)) return Rgb(0.0f);
  const Vec3 wi = to_light / std::sqrt(dist2);
  const float cos_light = -Dot(wi, ls.normal);
  if (cos_light <= 0.0f) return Rgb(0.0f);  // the back of a one-sided emitter
  const Rgb f = bsdf.EvalLobes(wo, wi, lobes);
  if (f.IsBlack()) return Rgb(0.0f);
  ++counters.shadow_rays;
  if (!scene.Visible(x, bsdf.geometric_normal(), ls.position, ls.normal)) return Rgb(0.0f);
  const float cos_surface = std::fabs(Dot(wi, bsdf.shading_normal()));
  return f * ls.radiance * (cos_surface * cos_light / (dist2 * ls.pdf_area));
}

MonteCarloDirectLight::MonteCarloDirectLight(const EmbreeScene& scene, const LightSampler& lights,
                                             DirectLightOptions options)
    : scene_(scene), lights_(lights), options_(options), choice_(lights, options.uniform_fraction) {}

Rgb MonteCarloDirectLight::Estimate(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes,
                                    Sampler& sampler, const PathVertexSlots& slots,
                                    TraceCounters& counters) const {
  if (choice_.empty() || !bsdf.HasNonDelta()) return Rgb(0.0f);
  const int n = std::max(1, options_.shadow_rays);
  Rgb sum(0.0f);
  for (int j = 0; j < n; ++j) {
    // Stratified over the lights' CDF: light i receives N·p_i ± 1 of the N rays (§4.2.1).
    const uint32_t sj = uint32_t(j), sn = uint32_t(n);
    const float u = (float(j) + sampler.Get1D(slots.light_stratum, sj, sn)) / float(n);
    const LightChoice::Choice light = choice_.Choose(u);
    if (!(light.probability > 0.0f)) continue;  // an empty stratum: u cannot land in it
    const float u_select = sampler.Get1D(slots.light_select, sj, sn);
    const Rgb c = SampleOneLight(scene_, lights_, light.light, bsdf, x, wo, lobes, u_select,
                                 sampler.Get2D(slots.light_point, sj, sn), counters);
    sum += c * (1.0f / light.probability);
  }
  return sum * (1.0f / float(n));
}

PhotonDirectLight::PhotonDirectLight(const EmbreeScene& scene, const LightSampler& lights,
                                     const PhotonMap& direct_map,
                                     const std::vector<uint32_t>& light_of_photon,
                                     PhotonDirectOptions options)
    : scene_(scene),
      lights_(lights),
      map_(direct_map),
      light_of_photon_(light_of_photon),
      options_(options) {}

Rgb PhotonDirectLight::Estimate(const Bsdf& bsdf, const Vec3& x, const Vec3& wo, uint32_t lobes,
                                Sampler& sampler, const PathVertexSlots& slots, TraceCounters& counters,
                                NearestPhotons& nearest) const {
  const size_t num_lights = lights_.num_lights();
  if (num_lights == 0 || !bsdf.HasNonDelta()) return Rgb(0.0f);
  // Per-thread neighbour-set cache (§4.2.3): the contributing lights and their sample counts.
  struct Cache {
    bool valid = false;
    uint64_t epoch = 0;
    const PhotonMap* map = nullptr;
    Vec3 x, n;
    float radius = 0;
    std::vector<uint32_t> lights;  // contributing light indices
    std::vector<int> samples;      // N_i
    std::vector<uint8_t> contributing;
  };
  thread_local Cache cache;
  const Vec3& ng = bsdf.geometric_normal();
  const Vec3 side = Dot(wo, ng) >= 0.0f ? ng : -ng;
  const bool hit = options_.cache_radius_fraction > 0 && cache.valid && cache.map == &map_ &&
                   cache.epoch == t_pixel_epoch &&
                   LengthSquared(x - cache.x) < Sq(options_.cache_radius_fraction * cache.radius) &&
                   Dot(cache.n, side) > 0.9f;
  if (!hit) {
    const auto filter =
        FunctionFilter([&](const Photon& p, std::size_t) { return Dot(p.Direction(), side) > 0.0f; });
    map_.Query(x, options_.k, options_.max_radius, nearest, &filter);
    thread_local std::vector<double> energy;
    energy.assign(num_lights, 0.0);
    double total = 0;
    for (const auto& e : nearest.entries()) {
      const size_t light = lights_.LightIndex(light_of_photon_[e.index]);
      if (light >= num_lights) continue;
      const double l = map_.photon(e.index).Power().Luminance();
      energy[light] += l;
      total += l;
    }
    cache.valid = true;
    cache.epoch = t_pixel_epoch;
    cache.map = &map_;
    cache.x = x;
    cache.n = side;
    cache.radius = std::sqrt(nearest.MaxDistanceSquared());
    cache.lights.clear();
    cache.samples.clear();
    cache.contributing.assign(num_lights, 0);
    for (size_t i = 0; i < num_lights; ++i)
      if (energy[i] > 0.0) {
        cache.lights.push_back(uint32_t(i));
        cache.samples.push_back(std::max(1, int(std::lround(options_.samples * energy[i] / total))));
        cache.contributing[i] = 1;
      }
  }
  Rgb sum(0.0f);
  const uint32_t n_total = uint32_t(std::max(1, options_.samples));
  uint32_t ray = 0;  // sub-index over all contributing lights' rays; beyond N_total: independent
  for (size_t c = 0; c < cache.lights.size(); ++c) {
    const int ni = cache.samples[c];
    Rgb li(0.0f);
    for (int j = 0; j < ni; ++j, ++ray) {
      const float u_select = (float(j) + sampler.Get1D(slots.light_stratum, ray, n_total)) / float(ni);
      li += SampleOneLight(scene_, lights_, cache.lights[c], bsdf, x, wo, lobes, u_select,
                           sampler.Get2D(slots.light_point, ray, n_total), counters);
    }
    sum += li * (1.0f / float(ni));
  }
  const size_t non_contributing = num_lights - cache.lights.size();
  if (non_contributing > 0) {
    if (options_.non_contributing == NonContributingMode::kEachOne) {
      for (size_t i = 0; i < num_lights; ++i)
        if (!cache.contributing[i]) {
          // Call order fixed by the locals (arguments are evaluated in any order).
          const float u_select = sampler.rng().Uniform();
          const Sample2 u{sampler.rng().Uniform(), sampler.rng().Uniform()};
          sum += SampleOneLight(scene_, lights_, i, bsdf, x, wo, lobes, u_select, u, counters);
        }
    } else {
      // One sample to the m-th non-contributing light, m uniform, weighted by their number.
      size_t m = sampler.rng().UniformInt(uint32_t(non_contributing));
      for (size_t i = 0; i < num_lights; ++i) {
        if (cache.contributing[i]) continue;
        if (m-- == 0) {
          const float u_select = sampler.Get1D(slots.light_select);
          const Sample2 u = sampler.Get2D(slots.light_extra);
          sum += SampleOneLight(scene_, lights_, i, bsdf, x, wo, lobes, u_select, u, counters) *
                 float(non_contributing);
          break;
        }
      }
    }
  }
  return sum;
}

}  // namespace pf
