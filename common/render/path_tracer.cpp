#include "common/render/path_tracer.h"

#include <optional>

#include "common/estimators/direct_light.h"
#include "common/materials/bsdf.h"
#include "common/sampling/sample_layout.h"
#include "common/scene/surface_material.h"

namespace pf {
namespace {

// Veach's power heuristic (β = 2) for two strategies with one sample each.
inline float PowerHeuristic(float pdf_a, float pdf_b) {
  const float a = pdf_a * pdf_a, b = pdf_b * pdf_b;
  return a + b > 0.0f ? a / (a + b) : 0.0f;
}

}  // namespace

PathTracer::PathTracer(const EmbreeScene& scene, const LightSampler& lights, PathTracerOptions options)
    : scene_(scene), lights_(lights), options_(options), choice_(lights, options.nee_uniform_fraction) {}

Rgb PathTracer::LightSampleEstimate(const SurfaceHit& hit, const Bsdf& bsdf, const Vec3& wo,
                                    const Rgb& throughput, Sampler& sampler, const PathVertexSlots& slots,
                                    TraceCounters& counters) const {
  const LightChoice::Choice light = choice_.Choose(sampler.Get1D(slots.light_select));
  const Sample2 u = sampler.Get2D(slots.light_point);
  // Choose never lands in an empty stratum for u < 1; a zero probability would divide below.
  if (!(light.probability > 0.0f)) return Rgb(0.0f);
  LightSample ls = lights_.SampleLight(light.light, light.u, u.u, u.v);
  // The choice's probability into the sample's density, as the rest of this step expects.
  ls.pdf_area *= light.probability;
  if (ls.delta()) {
    // A point, spot or directional light: no BSDF sample can reach it, so no MIS weight.
    return throughput * DeltaLightContribution(lights_, ls, bsdf, hit.position, wo, kLobeAll, counters);
  }
  if (ls.environment) {
    const Rgb c = EnvironmentLightContribution(lights_, ls, bsdf, hit.position, wo, kLobeAll, counters);
    return c.IsBlack() ? c
                       : throughput * c * PowerHeuristic(ls.pdf_area * ls.pdf_direction, bsdf.Pdf(wo, ls.wi));
  }
  const Vec3 to_light = ls.position - hit.position;
  const float dist2 = LengthSquared(to_light);
  if (!(dist2 > 0.0f)) return Rgb(0.0f);
  const Vec3 wi = to_light / std::sqrt(dist2);
  const float cos_light = -Dot(wi, ls.normal);
  if (cos_light <= 0.0f) return Rgb(0.0f);
  const Rgb f = bsdf.Eval(wo, wi);
  if (f.IsBlack()) return Rgb(0.0f);
  ++counters.shadow_rays;
  if (!scene_.Visible(hit.position, hit.geometric_normal, ls.position, ls.normal)) return Rgb(0.0f);
  const float pdf_light = ls.pdf_area * dist2 / cos_light;
  const float weight = PowerHeuristic(pdf_light, bsdf.Pdf(wo, wi));
  const float cos_surface = std::fabs(Dot(wi, hit.shading_normal));
  return throughput * f * ls.radiance * (cos_surface * weight / pdf_light);
}

Rgb PathTracer::Li(const Ray& camera_ray, Sampler& sampler, TraceCounters& counters) const {
  const SceneDescription& desc = scene_.description();
  Rgb radiance(0.0f);
  Rgb throughput(1.0f);
  Ray ray = camera_ray;
  bool previous_was_delta = true;  // camera rays see emitters with full weight
  float previous_pdf = 0.0f;       // solid-angle pdf of the BSDF sample that made `ray`
  Vec3 previous_position = ray.origin;

  for (int depth = 0; depth < options_.max_depth; ++depth) {
    ++counters.rays;
    const std::optional<SurfaceHit> hit = scene_.Intersect(ray);
    if (!hit) {
      // The environment seen by an escaping ray, MIS-weighted against light sampling like an
      // emitter's emission below.
      if (const EnvironmentLight* environment = lights_.environment()) {
        const Rgb le = environment->Radiance(ray.direction);
        radiance +=
            throughput * le *
            (previous_was_delta ? 1.0f : PowerHeuristic(previous_pdf, choice_.PdfEnvironment(ray.direction)));
      }
      break;
    }
    std::optional<Material> textured;  // filled only for a textured material
    const Material& material = MaterialAt(desc, hit->material, hit->uv, &textured);
    const PathVertexSlots slots = SlotsOfVertex(depth);

    // Emission seen by the BSDF-sampled ray, MIS-weighted against light sampling.
    if (material.IsEmissive() && hit->front_face) {
      if (previous_was_delta || lights_.empty()) {
        radiance += throughput * material.emission;
      } else {
        const float cos_light = -Dot(ray.direction, hit->geometric_normal);
        const float dist2 = LengthSquared(hit->position - previous_position);
        const float pdf_light = choice_.PdfArea(hit->triangle) * dist2 / cos_light;
        radiance += throughput * material.emission * PowerHeuristic(previous_pdf, pdf_light);
      }
    }

    const Bsdf bsdf(material, hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;

    // Next-event estimation: one light sample, MIS-weighted against BSDF sampling.
    if (bsdf.HasNonDelta() && !choice_.empty())
      radiance += LightSampleEstimate(*hit, bsdf, wo, throughput, sampler, slots, counters);

    // Continue the path by sampling the BSDF.
    const float u_lobe = sampler.Get1D(slots.bsdf_lobe);
    const Sample2 u = sampler.Get2D(slots.bsdf_dir);
    const std::optional<BsdfSample> s = bsdf.Sample(wo, u_lobe, u.u, u.v);
    if (!s || s->weight.IsBlack()) break;
    throughput *= s->weight;
    previous_was_delta = s->is_delta;
    // The full mixture pdf of the non-delta lobes, exactly what NEE's MIS weight used.
    previous_pdf = s->is_delta ? 0.0f : bsdf.Pdf(wo, s->wi);
    previous_position = hit->position;
    ray = Ray{scene_.SpawnOrigin(*hit, s->wi), s->wi};

    // Russian roulette (Arvo & Kirk 1990): unbiased termination of low-throughput paths.
    if (depth + 1 >= options_.rr_start_depth) {
      const float survive = std::min(1.0f, throughput.Max());
      if (!(survive > 0.0f) || sampler.Get1D(slots.roulette) >= survive) break;
      throughput *= 1.0f / survive;
    }
  }
  return radiance;
}

}  // namespace pf
