#include "common/photon/metropolis_chain.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "common/scene/surface_material.h"

namespace pf {
namespace {

// The start's density (up to its constant) for direction w: 0 where the walk could not go.
double StartDensity(const ChainStart& c, const Vec3& w) {
  if (!(Dot(w, c.side) > 0.0f)) return 0.0;
  return std::max(0.0, double(Dot(w, c.axis)));
}

// Φ leaving the start in direction w (the diffuse bounce's RR weight depends on w only when the
// lobe axis is not the shading normal).
Rgb StartPower(const ChainStart& c, const Vec3& w) {
  if (!c.bsdf) return c.power;
  const float cos_axis = Dot(w, c.axis);
  if (!(cos_axis > 0.0f)) return Rgb(0.0f);
  const Rgb f = c.bsdf->EvalLobes(c.wo, w, kLobeDiffuseReflection);
  return c.power * f * (c.bsdf->AbsCosTheta(w) * kPi / cos_axis) * c.diffuse_roulette;
}

// Traces the chain of `like`'s characteristic from the start in direction w; false when the
// geometry does not give that characteristic (Q = 0).
bool TraceChain(const EmbreeScene& scene, const ChainStart& c, const ChainState& like, const Vec3& w,
                uint32_t light, MetropolisCounts& counts, ChainState* result) {
  const SceneDescription& desc = scene.description();
  result->lobes = like.lobes;
  result->escaped = like.escaped;
  result->direction = w;
  result->stores.clear();
  result->q = 1.0;
  Rgb power = StartPower(c, w);
  if (power.IsBlack()) return false;
  Ray ray{c.hit ? scene.SpawnOrigin(*c.hit, w) : c.ray_origin_light, w};
  Vec3 previous = ray.origin;  // off the surface, as TracedPhoton::origin
  const size_t n = like.lobes.size();
  for (size_t i = 0; i <= n; ++i) {
    ++counts.rays;
    const std::optional<SurfaceHit> hit = scene.Intersect(ray);
    if (!hit) return i == n && like.escaped;
    if (i == n && like.escaped) return false;
    std::optional<Material> textured;  // filled only for a textured material
    const Material& m = MaterialAt(desc, hit->material, hit->uv, &textured);
    const Bsdf bsdf(m, hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;
    if (i >= 1 && bsdf.HasDiffuse())
      result->stores.push_back({hit->position, wo, power, previous, light, PhotonKind::kCaustic});
    if (i == n) {
      result->q *= 1.0 - double(bsdf.RouletteProbability(wo, kSingularLobes));
      return result->q > 0.0;
    }
    const std::optional<BsdfSample> s =
        bsdf.Sample(wo, 0.0f, 0.5f, 0.5f, Bsdf::Mode::kRussianRoulette, like.lobes[i]);
    if (!s || s->lobe != like.lobes[i] || !(s->pdf > 0.0f)) return false;
    result->q *= double(s->pdf);
    power *= s->weight;
    if (power.IsBlack() || !power.IsFinite()) return false;
    ray = Ray{scene.SpawnOrigin(*hit, s->wi), s->wi};
    previous = ray.origin;
  }
  return false;
}

// A direction at angle θ (exponentially distributed between the jitter bounds) from w.
Vec3 JitterDirection(const Vec3& w, Rng& rng) {
  const float u1 = rng.Uniform(), u2 = rng.Uniform();
  const float theta =
      kMetropolisJitterMax * std::exp(std::log(kMetropolisJitterMin / kMetropolisJitterMax) * u1);
  const float phi = kTwoPi * u2;
  const float st = std::sin(theta);
  return Normalize(Frame(w).ToWorld(Vec3(st * std::cos(phi), st * std::sin(phi), std::cos(theta))));
}

}  // namespace

void StoreWeighted(const std::vector<TracedPhoton>& stores, float scale, TracedPhotons& caustic) {
  for (TracedPhoton p : stores) {
    p.power *= scale;
    caustic.push_back(p);
  }
}

// Wald 1999, §4.6.2: S states of a Markov chain over the start direction whose stationary
// density is pdf(ω)·Q(ω) restricted to the characteristic — the density the original chain was
// drawn from, given its characteristic — so each state is distributed as the original and the
// weighted mean of their stores has the original's expectation (docs/renderer.md).
void SplitChain(const EmbreeScene& scene, const ChainStart& c, ChainState& original, uint32_t split,
                uint32_t light, Rng& rng, TracedPhotons& caustic, MetropolisCounts& counts) {
  ++counts.chains;
  ChainState current = std::move(original), proposal;
  double current_density = StartDensity(c, current.direction) * current.q;
  uint32_t weight = 1;
  const float scale = 1.0f / float(split);
  for (uint32_t t = 1; t < split; ++t) {
    ++counts.mutations;
    const Vec3 w = JitterDirection(current.direction, rng);
    const float u = rng.Uniform();
    const double start_density = StartDensity(c, w);
    if (start_density > 0.0 && TraceChain(scene, c, current, w, light, counts, &proposal)) {
      const double density = start_density * proposal.q;
      if (double(u) * current_density < density) {
        ++counts.accepted;
        StoreWeighted(current.stores, float(weight) * scale, caustic);
        std::swap(current, proposal);
        current_density = density;
        weight = 1;
        continue;
      }
    }
    ++weight;
  }
  StoreWeighted(current.stores, float(weight) * scale, caustic);
}

}  // namespace pf
