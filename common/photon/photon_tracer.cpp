#include "common/photon/photon_tracer.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "common/core/error.h"
#include "common/materials/bsdf.h"
#include "common/photon/metropolis_chain.h"
#include "common/sampling/sample_layout.h"
#include "common/scene/surface_material.h"

namespace pf {

Rgb PhotonTracingResult::StoredPower() const {
  // Summed in double: millions of small powers lose digits in float.
  double r = 0, g = 0, b = 0;
  for (const auto* list : {&direct, &indirect, &caustic})
    for (const TracedPhoton& p : *list) {
      r += p.power.r;
      g += p.power.g;
      b += p.power.b;
    }
  return Rgb(float(r), float(g), float(b));
}

bool SceneNeedsCausticMap(const SceneDescription& scene) {
  for (const Material& m : scene.materials)
    if (!m.specular_reflectance.IsBlack() || !m.specular_transmittance.IsBlack()) return true;
  return false;
}

const char* CausticSplitMethodName(CausticSplitMethod m) {
  return m == CausticSplitMethod::kMetropolis ? "metropolis" : "brute";
}

namespace {

// A punctual light's emitter (photon_tracer.h, PhotonEmitter): Φ/(p·N) per photon, every photon
// of the light carrying the same power because its directions follow the light's own angular
// distribution (and a directional light's points are uniform on its disc).
PhotonEmitter PunctualPhotonEmitter(const PunctualEmitter& p, float p_select, uint64_t emitted) {
  PhotonEmitter e;
  e.punctual = true;
  e.kind = p.kind;
  e.normal = p.direction;
  e.frame = Frame(p.direction);
  e.power = p.power * (1.0f / (p_select * float(emitted)));
  e.light = p.light;
  e.a = p.position;
  if (p.kind == PunctualLight::Kind::kSpot) {
    e.cos_inner = p.cos_inner;
    e.cos_outer = p.cos_outer;
    const float cap = 1.0f - p.cos_inner, ramp = (p.cos_inner - p.cos_outer) / 3.0f;
    e.cap_probability = cap / (cap + ramp);
  } else if (p.kind == PunctualLight::Kind::kDirectional) {
    e.radius = p.radius;
    // The disc stands beyond the bounding sphere, facing along the light (a little beyond it, so
    // that no surface on the sphere is in front of a photon's origin).
    e.a = p.position - p.direction * (1.01f * p.radius);
  }
  return e;
}

}  // namespace

std::vector<PhotonEmitter> PhotonEmitters(const SceneDescription& desc, const LightSampler& lights,
                                          uint64_t emitted) {
  std::vector<PhotonEmitter> emitters;
  emitters.reserve(lights.num_emitters());
  for (size_t i = 0; i < lights.num_emitters(); ++i) {
    const LightSample ls = lights.EmitterSample(i, 0.0f, 0.0f);
    if (ls.environment) {
      PhotonEmitter e;
      e.punctual = true;
      e.environment = lights.environment();
      e.radius = e.environment->radius();
      e.power = Rgb(kPi * e.radius * e.radius / (ls.pdf_area * float(emitted)));
      e.light = ls.light;
      emitters.push_back(e);
      continue;
    }
    if (ls.delta()) {
      emitters.push_back(PunctualPhotonEmitter(lights.punctual()[ls.punctual], ls.pdf_area, emitted));
      continue;
    }
    const auto& t = desc.triangles[ls.triangle];
    PhotonEmitter e;
    e.a = desc.positions[t[0]];
    e.b = desc.positions[t[1]];
    e.c = desc.positions[t[2]];
    e.normal = ls.normal;
    e.frame = Frame(ls.normal);
    // Φ = Le·π·A / (p_select·N): the pdf already holds p_select/A.
    e.power = ls.radiance * (kPi / (ls.pdf_area * float(emitted)));
    const Material& m = desc.materials[desc.triangle_material[ls.triangle]];
    if (m.emission_texture >= 0 && !desc.uvs.empty()) {
      // Le·texel(x) per photon (Emit): the sample above read the texel at one corner.
      e.power = m.emission * (kPi / (ls.pdf_area * float(emitted)));
      e.emission_texture = &desc.textures[size_t(m.emission_texture)];
      e.uv_a = desc.uvs[t[0]];
      e.uv_b = desc.uvs[t[1]];
      e.uv_c = desc.uvs[t[2]];
    }
    e.light = ls.light;
    emitters.push_back(e);
  }
  return emitters;
}

namespace {

constexpr uint64_t kChunk = kPhotonTracingChunk;
constexpr uint64_t kSplitTag = 0x73706c6974ull;     // "split": brute force's choice j*
constexpr uint64_t kMetropolisTag = 0x6d636d63ull;  // "mcmc": Metropolis mutations

struct ChunkOutput {
  TracedPhotons direct, indirect, caustic;
  // Metropolis splitting's per-photon state (§4.6.2), allocated at the chunk's first Metropolis
  // photon and reset for each one after it: no allocation per photon.
  std::unique_ptr<MetropolisWalk> metropolis_walk;
  uint64_t rays = 0, rejected = 0;
  MetropolisCounts metropolis;
  ImportanceScratch importance_scratch;  // the chunk's importance queries (one thread at a time)
};

// What every photon of one trace shares, computed once per TracePhotons call rather than at
// every photon or hit: the sampler's per-slot seeds of the map (sampler.h, PhotonStream) and
// each material's lobe selection means (§2.2, bsdf.h, BsdfLobes); for the plain walk (no
// Metropolis chain) also the emitter table (Emitter) and each material's WalkRoulette (bsdf.h: a
// flat hit's roulette without building a Bsdf). Each gives exactly the values the per-photon /
// per-hit computation gives, so the maps are the same bit for bit.
struct TraceShared {
  TraceShared(const SceneDescription& desc, const LightSampler& lights, const PhotonTracerOptions& o)
      : stream(o.sampler, o.map_seed),
        emitted(o.caustic_split > 1 && o.caustic_split_method == CausticSplitMethod::kBrute
                    ? o.photons * o.caustic_split
                    : o.photons),
        emitters(PhotonEmitters(desc, lights, emitted)) {
    lobes.reserve(desc.materials.size());
    walk.reserve(desc.materials.size());
    for (const Material& m : desc.materials)
      walk.push_back(WalkRoulette::Of(m, lobes.emplace_back(BsdfLobes::Of(m))));
  }
  PhotonStream stream;
  uint64_t emitted;  // emitted photons of the whole map, N (§4.6.1: N·S when split by brute force)
  std::vector<PhotonEmitter> emitters;  // by LightSampler::EmitterIndex
  std::vector<BsdfLobes> lobes;         // by material index
  std::vector<WalkRoulette> walk;       // by material index
};

// Stratified light choice: photon i takes the i-th stratum of [0,1), so every light gets
// N·p_light photons up to ±1 (§2.2: photons per light ∝ its power).
float StratifiedLightUniform(double jitter, uint64_t index, uint64_t emitted) {
  return std::min(float((double(index) + jitter) / double(emitted)), 0x1.fffffep-1f);
}

// What TraceRange computes ahead for a photon of a batch: its Sobol lanes (PhotonStream::Lanes)
// and its emitter (the trace's emitter table, at LightSampler::EmitterIndex of its light choice).
// (Computing the point and the first ray ahead too was slower: 51–59 % of the raw ray rate
// against 60–62 % on Cornell, docs/results/kernel.md §4.)
struct PhotonStart {
  PhotonLanes lanes;
  const PhotonEmitter* emitter = nullptr;
};

// The photon's emitter, from its light stratum's jitter (the photon's first number).
const PhotonEmitter& EmitterOf(const LightSampler& lights, const TraceShared& shared, double jitter,
                               uint64_t index) {
  return shared.emitters[lights.EmitterIndex(StratifiedLightUniform(jitter, index, shared.emitted))];
}
const PhotonEmitter& ChooseEmitter(const LightSampler& lights, const PhotonTracerOptions& o,
                                   const TraceShared& shared, Sampler& sampler, uint64_t index) {
  return EmitterOf(lights, shared,
                   o.sampler == SamplerKind::kSobol ? double(sampler.Get1D(kPhotonLightSlot))
                                                    : sampler.rng().UniformDouble(),
                   index);
}

// A photon leaving emitter `em` (§2.2): a uniform point on it and a cosine-distributed first ray,
// from the photon's point and direction numbers. Forced inline: out of line (two callers), the
// call and the returned struct were 1.6 % of a Cornell trace's instructions.
struct Emission {
  Vec3 position;
  Ray ray;
  Rgb power;  // the photon's: the emitter's, or for the environment's per direction
};

// An environment photon (environment_light.h): direction ω by its distribution from u_dir, a
// uniform point of the disc of radius R perpendicular to ω from u_point, the disc's centre
// beyond the bounding sphere (as a directional light's), travelling along −ω.
Emission EmitEnvironment(const PhotonEmitter& em, Sample2 u_point, Sample2 u_dir) {
  const EnvironmentLight& env = *em.environment;
  const EnvironmentLight::DirectionSample d = env.Sample(u_dir.u, u_dir.v);
  const Frame frame(-d.wi);
  float ds, dc;
  SinCos2Pi(u_point.v, &ds, &dc);
  const float r = em.radius * std::sqrt(u_point.u);
  Emission e;
  e.position = env.centre() + d.wi * (1.01f * em.radius) + frame.s * (r * dc) + frame.t * (r * ds);
  e.ray = Ray{e.position, -d.wi};
  e.power = d.pdf > 0.0f ? em.power * d.radiance * (1.0f / d.pdf) : Rgb(0.0f);
  return e;
}
// A punctual light's photon from the same two numbers (photon_tracer.h, PhotonEmitter): from its
// point, uniform over the sphere (point) or ∝ the falloff within the cone (spot), or from a
// uniform point of its disc (directional). Nothing to offset: no surface emits it.
Emission EmitPunctual(const PhotonEmitter& em, Sample2 u_point, Sample2 u_dir) {
  Emission e;
  e.position = em.a;
  Vec3 local;
  float s, c;
  SinCos2Pi(u_dir.v, &s, &c);
  switch (em.kind) {
    case PunctualLight::Kind::kPoint: {
      const float z = 1.0f - 2.0f * u_dir.u;
      const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
      local = Vec3(r * c, r * s, z);
      break;
    }
    case PunctualLight::Kind::kSpot: {
      // cos θ: uniform on the flat cap [cos θi, 1], or on the ramp with density ∝ t², t =
      // (cos θ − cos θo)/(cos θi − cos θo), whose inverse CDF is t = ∛u.
      float cos_theta;
      if (u_dir.u < em.cap_probability) {
        cos_theta = 1.0f - (u_dir.u / em.cap_probability) * (1.0f - em.cos_inner);
      } else {
        const float u = (u_dir.u - em.cap_probability) / (1.0f - em.cap_probability);
        cos_theta = em.cos_outer + std::cbrt(u) * (em.cos_inner - em.cos_outer);
      }
      const float r = std::sqrt(std::max(0.0f, 1.0f - cos_theta * cos_theta));
      local = Vec3(r * c, r * s, cos_theta);
      break;
    }
    case PunctualLight::Kind::kDirectional: {
      float ds, dc;
      SinCos2Pi(u_point.v, &ds, &dc);
      const float r = em.radius * std::sqrt(u_point.u);
      e.position = em.a + em.frame.s * (r * dc) + em.frame.t * (r * ds);
      local = Vec3(0.0f, 0.0f, 1.0f);
      break;
    }
  }
  e.ray = Ray{e.position, Normalize(em.frame.ToWorld(local))};
  e.power = em.power;
  return e;
}

[[gnu::always_inline]] inline Emission EmitFrom(const PhotonEmitter& em, Sample2 u_point, Sample2 u_dir,
                                                float epsilon) {
  Emission e;
  if (em.punctual) [[unlikely]] {
    if (em.environment) return EmitEnvironment(em, u_point, u_dir);
    return EmitPunctual(em, u_point, u_dir);
  }
  e.position = SampleTriangle(em.a, em.b, em.c, u_point.u, u_point.v);
  e.ray = Ray{OffsetRayOrigin(e.position, em.normal, epsilon),
              em.frame.ToWorld(CosineHemisphereFast(u_dir.u, u_dir.v))};
  e.power = em.power;
  if (em.emission_texture) [[unlikely]]
    e.power =
        em.power * em.emission_texture->Lookup(UvOnTriangle(em.uv_a, em.uv_b, em.uv_c, u_point.u, u_point.v));
  return e;
}

// The point's numbers are drawn before the direction's (the order of every trace so far).
[[gnu::always_inline]] inline Emission Emit(const PhotonEmitter& em, Sampler& sampler, float epsilon) {
  const Sample2 u_point = sampler.PhotonGet2D(kPhotonPointSlot);
  return EmitFrom(em, u_point, sampler.PhotonGet2D(kPhotonDirectionSlot), epsilon);
}

// Importance-driven storing (Wald 1999, §4.7): a storing hit keeps its photon with probability
// p at power Φ/p (the walk goes on either way). False: this photon is not stored.
bool AcceptByImportance(const PhotonTracerOptions& o, Sampler& sampler, int bounce, const Vec3& position,
                        const Vec3& ng, const Vec3& wo, Rgb* stored_power, ChunkOutput& out) {
  const Vec3 facing = Dot(ng, wo) >= 0.0f ? ng : -ng;
  const float p = o.importance->AcceptanceProbability(position, facing, out.importance_scratch);
  if (!(p < 1.0f)) return true;
  if (!(sampler.Get1D(SlotOfPhotonAcceptance(bounce)) < p)) {
    ++out.rejected;
    return false;
  }
  *stored_power = *stored_power / p;
  return true;
}

// A photon stored outside a Metropolis chain: a caustic one (§2.2: the path since the last
// diffuse bounce was singular), or a direct or indirect one, kept only by the emitted photon
// that keeps them under brute-force splitting (§4.6.1), at S× its power.
void StorePhoton(ChunkOutput& out, int bounce, bool caustic, bool keep_noncaustic, float noncaustic_scale,
                 const Vec3& position, const Vec3& wo, Rgb power, const Vec3& previous, uint32_t light) {
  if (caustic) {
    AppendPhoton(out.caustic, position, wo, power, previous, light, PhotonKind::kCaustic);
  } else if (keep_noncaustic) {
    if (noncaustic_scale != 1.0f) power *= noncaustic_scale;
    AppendPhoton(bounce == 0 ? out.direct : out.indirect, position, wo, power, previous, light,
                 bounce == 0 ? PhotonKind::kDirect : PhotonKind::kIndirect);
  }
}

// The photon random walk of Wald 1999, §2.2, without Metropolis splitting (TraceEmitted below
// walks that one, with Intersect and a Bsdf at every hit as every trace did before this function
// existed: the same photons bit for bit, test PhotonTracer.PlainWalkStoresTheGeneralWalksPhotons).
// Cheaper per hit: the hit from IntersectWalk and the roulette of a flat hit from WalkRoulette
// (bsdf.h) — Bsdf::Sample only for the outcomes it leaves to it (another lobe than diffuse
// reflection, smooth or dielectric hits). Same numbers in the same order: the same map.
// `start`: the photon's lanes and emitter computed ahead (TraceRange), or null.
void TracePlainWalk(const EmbreeScene& scene, const LightSampler& lights, const PhotonTracerOptions& o,
                    const TraceShared& shared, uint64_t index, bool keep_noncaustic, float noncaustic_scale,
                    ChunkOutput& out, const PhotonStart* start = nullptr) {
  const SceneDescription& desc = scene.description();
  Sampler sampler = start ? Sampler::ForPhoton(shared.stream, index, start->lanes)
                          : Sampler::ForPhoton(shared.stream, index);
  const PhotonEmitter& em = start ? *start->emitter : ChooseEmitter(lights, o, shared, sampler, index);
  const Emission e = Emit(em, sampler, scene.epsilon());
  Vec3 previous = e.ray.origin;  // a photon's origin: its last ray's start, off the surface (TracedPhoton)
  Ray ray = e.ray;
  Rgb power = e.power;
  const uint32_t light = em.light;
  bool any_singular_since_diffuse = false;
  WalkHit hit;
  // A textured material's lobes and roulette depend on the hit (surface_material.h): made per hit,
  // in scratch space built at the walk's first textured hit (an untextured walk builds none).
  struct TexturedHit {
    Material material;
    BsdfLobes lobes;
    WalkRoulette roulette;
  };
  std::optional<TexturedHit> textured;
  for (int bounce = 0; bounce < o.max_bounces; ++bounce) {
    ++out.rays;
    if (!scene.IntersectWalk(ray, &hit)) return;
    const WalkRoulette* walk = &shared.walk[hit.material];
    const Material* material = &desc.materials[hit.material];
    const BsdfLobes* lobes = &shared.lobes[hit.material];
    if (walk->textured) {
      if (!textured) textured.emplace();
      ApplyTexels(*material, TexelsAt(desc, *material, hit.uv), &textured->material);
      material = &textured->material;
      textured->lobes = BsdfLobes::Of(*material);
      textured->roulette = WalkRoulette::Of(*material, textured->lobes);
      lobes = &textured->lobes;
      walk = &textured->roulette;
    }
    const WalkRoulette& roulette = *walk;
    const Vec3 wo = -ray.direction;
    // Whether a photon is stored is the material's, not the texel's: a photon records incident
    // flux, and the albedo is read at the estimate's query point (a black texel stores photons
    // too, else the estimate next to it would find a hole).
    if (shared.walk[hit.material].Stores(hit.geometric_normal)) {
      Rgb stored_power = power;
      if (!o.importance ||
          AcceptByImportance(o, sampler, bounce, hit.position, hit.geometric_normal, wo, &stored_power, out))
        StorePhoton(out, bounce, bounce > 0 && any_singular_since_diffuse, keep_noncaustic, noncaustic_scale,
                    hit.position, wo, stored_power, previous, light);
    }
    const PhotonBounceSlots slots = SlotsOfPhotonBounce(bounce);
    const float ul = sampler.PhotonGet1D(slots.lobe);
    const Sample2 u = sampler.PhotonGet2D(slots.direction);
    Vec3 wi;
    Rgb weight;
    uint32_t lobe;
    const WalkRoulette::Outcome outcome =
        roulette.At(hit.geometric_normal, !hit.interpolated, wo, ul, u.u, u.v, &wi);
    if (outcome == WalkRoulette::Outcome::kAbsorbed) return;
    if (outcome == WalkRoulette::Outcome::kDiffuse) {
      weight = roulette.diffuse_weight;
      lobe = kLobeDiffuseReflection;
    } else {
      const Bsdf bsdf(*material, *lobes, hit.shading_normal, hit.geometric_normal);
      const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u.u, u.v, Bsdf::Mode::kRussianRoulette);
      if (!s) return;  // absorbed
      wi = s->wi;
      weight = s->weight;
      lobe = s->lobe;
    }
    power *= weight;
    if (power.IsBlack() || !power.IsFinite()) return;
    // A diffuse bounce resets the caustic test; a singular one makes the next store caustic.
    any_singular_since_diffuse = IsSingular(lobe);
    const Vec3& n = hit.geometric_normal;
    ray = Ray{OffsetRayOrigin(hit.position, Dot(wi, n) >= 0 ? n : -n, scene.epsilon()), wi};
    previous = ray.origin;
  }
}

// The walk with Metropolis caustic splitting (§4.6.2): TracePlainWalk's walks with Intersect and
// a Bsdf at every hit (the chains need the Bsdf), the same direct and indirect stores, and each
// singular chain's caustic stores weighted by the chain's Markov walk.
void TraceEmitted(const EmbreeScene& scene, const LightSampler& lights, const PhotonTracerOptions& o,
                  const TraceShared& shared, uint64_t index, ChunkOutput& out) {
  // Metropolis splitting emits N photons (§4.6.2) and keeps every store: map photon i is emitted
  // photon i.
  const uint64_t map_photon = index;
  const bool keep_noncaustic = true;
  const float noncaustic_scale = 1.0f;
  const SceneDescription& desc = scene.description();
  Sampler sampler = Sampler::ForPhoton(shared.stream, index);
  const PhotonEmitter& em = ChooseEmitter(lights, o, shared, sampler, index);
  const Emission e = Emit(em, sampler, scene.epsilon());
  Rgb power = e.power;
  const Vec3 dir = e.ray.direction;
  Vec3 previous = e.ray.origin;
  Ray ray = e.ray;

  // Metropolis splitting (§4.6.2): the chain being walked, if any. Its state is allocated by the
  // Metropolis walk only: as locals (or in a std::optional, whose storage GCC zeroes) its ~400
  // bytes were cleared for every photon of a plain walk (docs/results/kernel.md §4).
  const bool metropolis = o.caustic_split > 1 && o.caustic_split_method == CausticSplitMethod::kMetropolis;
  MetropolisWalk* mw = nullptr;
  if (metropolis) {
    if (!out.metropolis_walk) out.metropolis_walk = std::make_unique<MetropolisWalk>();
    mw = out.metropolis_walk.get();
    mw->chain.reset();  // a fresh walk: begin_chain resets the state, the mutations are set with it
    mw->mutations.reset();
    mw->state = ChainState();
  }
  const auto in_chain = [mw] { return mw && mw->chain; };
  auto begin_chain = [mw](ChainStart start) {
    mw->chain = std::move(start);
    mw->state = ChainState();
    mw->state.direction = mw->chain->direction;
  };
  auto end_chain = [&](bool escaped) {
    if (!in_chain()) return;
    ChainState& state = mw->state;
    if (!state.lobes.empty()) {
      state.escaped = escaped;
      if (state.splittable && state.q > 0.0) {
        if (!mw->mutations)
          mw->mutations = Rng::ForKey(HashKey(o.map_seed, map_photon, kMetropolisTag, index));
        SplitChain(scene, *mw->chain, state, o.caustic_split, em.light, *mw->mutations, out.caustic,
                   out.metropolis);
      } else {
        StoreWeighted(state.stores, 1.0f, out.caustic);
      }
    }
    mw->chain.reset();
  };
  // A chain starts at the light only for an area light: its mutations jitter the emitted
  // direction about the emitter's cosine lobe. A punctual light's caustics are stored unsplit
  // (weight 1, as a chain that cannot be split is) — unbiased, only not refined.
  if (metropolis && !em.punctual) {
    ChainStart start;
    start.ray_origin_light = ray.origin;
    start.axis = em.normal;
    start.side = em.normal;
    start.power = power;
    start.direction = dir;
    begin_chain(std::move(start));
  }

  bool any_singular_since_diffuse = false;
  for (int bounce = 0; bounce < o.max_bounces; ++bounce) {
    ++out.rays;
    const std::optional<SurfaceHit> hit = scene.Intersect(ray);
    if (!hit) {
      end_chain(true);
      return;
    }
    std::optional<Material> textured;  // filled only for a textured material
    const Material& m = MaterialAt(desc, hit->material, hit->uv, &textured);
    const Bsdf bsdf = IsTextured(desc.materials[hit->material])
                          ? Bsdf(m, hit->shading_normal, hit->geometric_normal)
                          : Bsdf(m, shared.lobes[hit->material], hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;
    Rgb stored_power = power;
    // (Metropolis splitting and importance-driven storing are never combined: TracePhotons.)
    // Storing is the material's, as in the plain walk: a textured material stores wherever a texel
    // could give it a diffuse lobe (WalkRoulette::Of), not only where this one does.
    const bool stores = IsTextured(desc.materials[hit->material])
                            ? shared.walk[hit->material].Stores(hit->geometric_normal)
                            : bsdf.HasDiffuse();
    if (stores && (!o.importance || AcceptByImportance(o, sampler, bounce, hit->position,
                                                       hit->geometric_normal, wo, &stored_power, out))) {
      const bool caustic = bounce > 0 && any_singular_since_diffuse;
      if (caustic && in_chain()) {
        // Weighted when the chain ends.
        mw->state.stores.push_back(
            {hit->position, wo, stored_power, previous, em.light, PhotonKind::kCaustic});
      } else {
        StorePhoton(out, bounce, caustic, keep_noncaustic, noncaustic_scale, hit->position, wo, stored_power,
                    previous, em.light);
      }
    }
    const PhotonBounceSlots slots = SlotsOfPhotonBounce(bounce);
    const float ul = sampler.Get1D(slots.lobe);
    const Sample2 u = sampler.Get2D(slots.direction);
    const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u.u, u.v, Bsdf::Mode::kRussianRoulette);
    if (in_chain()) {
      ChainState& state = mw->state;
      if (s && IsSingular(s->lobe)) {
        // The chain goes on: its characteristic and its probability factor grow.
        state.lobes.push_back(s->lobe);
        state.q *= double(s->pdf);
        if (IsGlossy(s->lobe)) state.splittable = false;
      } else {
        if (!state.lobes.empty()) state.q *= 1.0 - double(bsdf.RouletteProbability(wo, kSingularLobes));
        end_chain(false);
      }
    }
    if (!s) return;  // absorbed
    const Rgb arriving = power;
    power *= s->weight;
    if (power.IsBlack() || !power.IsFinite()) {
      if (in_chain()) mw->state.splittable = false;
      end_chain(false);
      return;
    }
    if (metropolis && s->lobe == kLobeDiffuseReflection) {
      if (const std::optional<Vec3> axis = bsdf.LobeAxis(wo)) {
        ChainStart start;
        start.hit = *hit;
        start.bsdf = bsdf;
        start.wo = wo;
        start.axis = *axis;
        start.side = Dot(wo, hit->geometric_normal) > 0.0f ? hit->geometric_normal : -hit->geometric_normal;
        start.power = arriving;
        start.diffuse_roulette = Rgb(1.0f / bsdf.RouletteProbability(wo, kLobeDiffuseReflection));
        start.direction = s->wi;
        begin_chain(std::move(start));
      }
    }
    // A diffuse bounce resets the caustic test; a singular one makes the next store caustic.
    any_singular_since_diffuse = IsSingular(s->lobe);
    ray = Ray{scene.SpawnOrigin(*hit, s->wi), s->wi};
    previous = ray.origin;
  }
  if (in_chain()) mw->state.splittable = false;  // the bounce cap ended it: stored unsplit
  end_chain(false);
}

void TraceOne(const EmbreeScene& scene, const LightSampler& lights, const PhotonTracerOptions& o,
              const TraceShared& shared, uint64_t index, ChunkOutput& out) {
  const uint32_t split = std::max<uint32_t>(1, o.caustic_split);
  if (split > 1 && o.caustic_split_method == CausticSplitMethod::kMetropolis) {
    TraceEmitted(scene, lights, o, shared, index, out);
    return;
  }
  if (split == 1) {
    TracePlainWalk(scene, lights, o, shared, index, true, 1.0f, out);
    return;
  }
  // Wald 1999, §4.6.1: map photon i stands for the emitted photons i·S .. i·S + S − 1; the one
  // whose non-caustic stores are kept is chosen uniformly (probability 1/S each, so the global
  // map is unbiased) and exactly one per map photon (so it keeps the size of an N-photon map).
  Rng rng = Rng::ForKey(HashKey(o.map_seed, index, kSplitTag));
  const uint32_t keep = rng.UniformInt(split);
  for (uint32_t j = 0; j < split; ++j)
    TracePlainWalk(scene, lights, o, shared, index * split + j, j == keep, float(split), out);
}

// Photons [begin, end) in order, into `out`. The plain walk's photons (no splitting) go in
// batches: first every photon's Sobol lanes and light choice in one loop, where the photons'
// independent hash chains and divisions overlap, then the walks — the same numbers as each walk
// computing its own (docs/results/kernel.md §4).
void TraceRange(const EmbreeScene& scene, const LightSampler& lights, const PhotonTracerOptions& o,
                const TraceShared& shared, uint64_t begin, uint64_t end, ChunkOutput& out) {
  if (o.caustic_split > 1 || end <= begin || !shared.stream.HasLanes(end - 1)) {
    for (uint64_t i = begin; i < end; ++i) TraceOne(scene, lights, o, shared, i, out);
    return;
  }
  constexpr uint64_t kBatch = 16;
  std::array<PhotonStart, kBatch> starts;
  for (uint64_t b = begin; b < end; b += kBatch) {
    const uint64_t n = std::min(kBatch, end - b);
    for (uint64_t k = 0; k < n; ++k) {
      shared.stream.Lanes(b + k, &starts[k].lanes);
      // The light stratum's jitter as the walk's sampler would read it (Sampler::ForPhoton with lanes).
      const double jitter = starts[k].lanes.u[sobol::kPhotonLaneOfSlot[kPhotonLightSlot]];
      starts[k].emitter = &EmitterOf(lights, shared, jitter, b + k);
    }
    for (uint64_t k = 0; k < n; ++k)
      TracePlainWalk(scene, lights, o, shared, b + k, true, 1.0f, out, &starts[k]);
  }
}

}  // namespace

PhotonLaunch LaunchPhoton(const PhotonEmitter& em, Sample2 u_point, Sample2 u_dir, float epsilon) {
  const Emission e = EmitFrom(em, u_point, u_dir, epsilon);
  return {e.ray, e.power};
}

PhotonTracingResult TracePhotons(const EmbreeScene& scene, const LightSampler& lights,
                                 const PhotonTracerOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  PhotonTracingResult result;
  const uint64_t range_end = options.photon_end == 0 ? options.photons : options.photon_end;
  if (options.photon_begin % kChunk != 0 || options.photon_begin > range_end || range_end > options.photons)
    throw std::invalid_argument("TracePhotons: photons [" + std::to_string(options.photon_begin) + ", " +
                                std::to_string(range_end) + ") of " + std::to_string(options.photons) +
                                " do not start at a multiple of " + std::to_string(kChunk));
  if (options.caustic_split > 1 && options.caustic_split_method == CausticSplitMethod::kMetropolis &&
      options.importance)
    throw std::invalid_argument("TracePhotons: Metropolis caustic splitting with importance-driven storing");
  if (lights.empty() || options.photons == 0) return result;
  const uint64_t first_chunk = options.photon_begin / kChunk;
  const uint64_t chunks = (range_end + kChunk - 1) / kChunk - first_chunk;
  std::vector<ChunkOutput> outputs(chunks);
  const TraceShared shared(scene.description(), lights, options);
  // The counts and totals, the same for both paths below (one thread, or chunks concatenated).
  const auto add_counts = [](const ChunkOutput& out, PhotonTracingResult* r) {
    r->rays += out.rays + out.metropolis.rays;
    r->rejected += out.rejected;
    r->chains += out.metropolis.chains;
    r->mutations += out.metropolis.mutations;
    r->accepted += out.metropolis.accepted;
  };
  const auto finish = [&](PhotonTracingResult* r) {
    r->emitted = range_end - options.photon_begin;
    if (options.caustic_split > 1 && options.caustic_split_method == CausticSplitMethod::kBrute)
      r->emitted *= options.caustic_split;  // §4.6.1: S emitted photons per map photon
    r->emitted_power = lights.total_power();
    r->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  tbb::task_arena arena(options.threads > 0 ? options.threads : tbb::task_arena::automatic);
  if (arena.max_concurrency() == 1) {
    // One thread traces the chunks in order anyway: straight into the result arrays, which
    // then need neither the per-chunk buffers nor the concatenation below (each photon's 56
    // bytes written once instead of twice, and half the page faults: a fifth of a 1-thread
    // trace's time went to faults and copies, docs/results/kernel.md §4). Same arrays.
    ChunkOutput out;
    for (uint64_t c = 0; c < chunks; ++c) {
      if (options.cancel && options.cancel->load(std::memory_order_relaxed)) throw Cancelled();
      const uint64_t end = std::min(range_end, (first_chunk + c + 1) * kChunk);
      TraceRange(scene, lights, options, shared, (first_chunk + c) * kChunk, end, out);
      if (c == 0 && chunks > 1) {
        // Room for the whole trace at the first chunk's rate, +25 %: address space only (pages
        // are touched as photons fill them); a growing vector would copy and fault its old buffers.
        const auto room = [&](size_t n) { return n + n * (chunks - 1) + n * chunks / 4 + 16; };
        out.direct.reserve(room(out.direct.size()));
        out.indirect.reserve(room(out.indirect.size()));
        out.caustic.reserve(room(out.caustic.size()));
      }
    }
    result.direct = std::move(out.direct);
    result.indirect = std::move(out.indirect);
    result.caustic = std::move(out.caustic);
    add_counts(out, &result);
    finish(&result);
    return result;
  }
  arena.execute([&] {
    tbb::parallel_for(uint64_t(0), chunks, [&](uint64_t c) {
      if (options.cancel && options.cancel->load(std::memory_order_relaxed)) return;
      const uint64_t end = std::min(range_end, (first_chunk + c + 1) * kChunk);
      // Room for the usual counts up front (a photon stores at most one direct photon, and
      // about one indirect one in the scenes we measured): a growing vector copies itself
      // and page-faults in every buffer it outgrows, which was ~1/3 of the memory traffic
      // of a trace. Reserving only takes address space; pages are touched as they are filled.
      ChunkOutput& out = outputs[c];
      out.direct.reserve(kChunk);
      out.indirect.reserve(2 * kChunk);
      TraceRange(scene, lights, options, shared, (first_chunk + c) * kChunk, end, out);
    });
  });
  if (options.cancel && options.cancel->load()) throw Cancelled();
  // Concatenated in chunk order (so the arrays are the same for any thread count), with the
  // copies (and their page faults) in parallel: ~84 MB of 56-byte photons for the default 1M
  // map, serial before, which Amdahl's law charges in full against every added thread
  // (docs/results/photon-parallel.md).
  std::vector<std::array<size_t, 3>> offsets(chunks + 1);
  for (uint64_t c = 0; c < chunks; ++c) {
    offsets[c + 1] = {offsets[c][0] + outputs[c].direct.size(), offsets[c][1] + outputs[c].indirect.size(),
                      offsets[c][2] + outputs[c].caustic.size()};
    add_counts(outputs[c], &result);
  }
  std::array<TracedPhotons*, 3> lists = {&result.direct, &result.indirect, &result.caustic};
  for (int k = 0; k < 3; ++k) lists[k]->resize(offsets[chunks][k]);
  arena.execute([&] {
    tbb::parallel_for(uint64_t(0), chunks, [&](uint64_t c) {
      ChunkOutput& out = outputs[c];
      const std::array<TracedPhotons*, 3> from = {&out.direct, &out.indirect, &out.caustic};
      for (int k = 0; k < 3; ++k) {
        // memmove (trivially copyable), which also begins the lifetimes of the photons in the
        // uninitialised memory of *lists[k].
        std::copy(from[k]->begin(), from[k]->end(), lists[k]->begin() + std::ptrdiff_t(offsets[c][k]));
        TracedPhotons().swap(*from[k]);  // peak memory: free each chunk once copied
      }
    });
  });
  finish(&result);
  return result;
}

}  // namespace pf
