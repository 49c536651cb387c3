#include "common/photon/photon_tracer.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <array>
#include <chrono>
#include <stdexcept>
#include <string>

#include "common/core/error.h"
#include "common/materials/bsdf.h"
#include "common/sampling/sample_layout.h"

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

namespace {

constexpr uint64_t kChunk = kPhotonTracingChunk;

struct ChunkOutput {
  TracedPhotons direct, indirect, caustic;
  uint64_t rays = 0, rejected = 0;
  ImportanceScratch importance_scratch;  // the chunk's importance queries (one thread at a time)
};

// Cosine-weighted direction around n.
Vec3 SampleCosineHemisphere(const Vec3& n, float u1, float u2) {
  const float r = std::sqrt(u1), phi = kTwoPi * u2;
  const float z = std::sqrt(std::max(0.0f, 1.0f - u1));
  return Frame(n).ToWorld(Vec3(r * std::cos(phi), r * std::sin(phi), z));
}

// What every photon of one trace shares, computed once per TracePhotons call rather than at
// every photon or hit: the sampler's per-slot seeds of the map (sampler.h, PhotonStream) and
// each material's lobe selection means (§2.2, bsdf.h, BsdfLobes). Both give exactly the values
// the per-photon / per-hit computation gave, so the maps are unchanged bit for bit.
struct TraceShared {
  TraceShared(const SceneDescription& desc, const PhotonTracerOptions& o) : stream(o.sampler, o.map_seed) {
    lobes.reserve(desc.materials.size());
    for (const Material& m : desc.materials) lobes.push_back(BsdfLobes::Of(m));
  }
  PhotonStream stream;
  std::vector<BsdfLobes> lobes;  // by material index
};

void TraceOne(const EmbreeScene& scene, const LightSampler& lights, const PhotonTracerOptions& o,
              const TraceShared& shared, uint64_t index, ChunkOutput& out) {
  const SceneDescription& desc = scene.description();
  Sampler sampler = Sampler::ForPhoton(shared.stream, index);
  // Stratified light choice: photon i takes the i-th stratum of [0,1), so every light gets
  // N·p_light photons up to ±1 (§2.2: photons per light ∝ its power).
  const double jitter = o.sampler == SamplerKind::kSobol ? double(sampler.Get1D(kPhotonLightSlot))
                                                         : sampler.rng().UniformDouble();
  const float u_select = float((double(index) + jitter) / double(o.photons));
  const Sample2 u_point = sampler.Get2D(kPhotonPointSlot);
  const LightSample ls = lights.Sample(std::min(u_select, 0x1.fffffep-1f), u_point.u, u_point.v);
  // Φ = Le·π·A / (p_select·N): the pdf already holds p_select/A.
  Rgb power = ls.radiance * (kPi / (ls.pdf_area * float(o.photons)));
  const Sample2 u_dir = sampler.Get2D(kPhotonDirectionSlot);
  Vec3 dir = SampleCosineHemisphere(ls.normal, u_dir.u, u_dir.v);
  Vec3 previous = ls.position;
  Ray ray{OffsetRayOrigin(ls.position, ls.normal, scene.epsilon()), dir};

  bool any_singular_since_diffuse = false;
  for (int bounce = 0; bounce < o.max_bounces; ++bounce) {
    ++out.rays;
    const std::optional<SurfaceHit> hit = scene.Intersect(ray);
    if (!hit) return;
    const Material& m = desc.materials[hit->material];
    const Bsdf bsdf(m, shared.lobes[hit->material], hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;
    bool store = bsdf.HasDiffuse();
    Rgb stored_power = power;
    if (store && o.importance) {
      // Wald 1999, §4.7: stored with probability p and power Φ/p; the walk goes on either way.
      const Vec3 facing =
          Dot(hit->geometric_normal, wo) >= 0.0f ? hit->geometric_normal : -hit->geometric_normal;
      const float p = o.importance->AcceptanceProbability(hit->position, facing, out.importance_scratch);
      if (p < 1.0f) {
        store = sampler.Get1D(SlotOfPhotonAcceptance(bounce)) < p;
        if (store)
          stored_power = power / p;
        else
          ++out.rejected;
      }
    }
    if (store) {
      TracedPhoton p{hit->position, wo, stored_power, previous, ls.light, PhotonKind::kIndirect};
      if (bounce == 0) {
        p.kind = PhotonKind::kDirect;
        out.direct.push_back(p);
      } else if (any_singular_since_diffuse) {
        p.kind = PhotonKind::kCaustic;
        out.caustic.push_back(p);
      } else {
        out.indirect.push_back(p);
      }
    }
    const PhotonBounceSlots slots = SlotsOfPhotonBounce(bounce);
    const float ul = sampler.Get1D(slots.lobe);
    const Sample2 u = sampler.Get2D(slots.direction);
    const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u.u, u.v, Bsdf::Mode::kRussianRoulette);
    if (!s) return;  // absorbed
    power *= s->weight;
    if (power.IsBlack() || !power.IsFinite()) return;
    // A diffuse bounce resets the caustic test; a singular one makes the next store caustic.
    any_singular_since_diffuse = IsSingular(s->lobe);
    previous = hit->position;
    ray = Ray{scene.SpawnOrigin(*hit, s->wi), s->wi};
  }
}

}  // namespace

PhotonTracingResult TracePhotons(const EmbreeScene& scene, const LightSampler& lights,
                                 const PhotonTracerOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  PhotonTracingResult result;
  const uint64_t range_end = options.photon_end == 0 ? options.photons : options.photon_end;
  if (options.photon_begin % kChunk != 0 || options.photon_begin > range_end || range_end > options.photons)
    throw std::invalid_argument("TracePhotons: photons [" + std::to_string(options.photon_begin) + ", " +
                                std::to_string(range_end) + ") of " + std::to_string(options.photons) +
                                " do not start at a multiple of " + std::to_string(kChunk));
  if (lights.empty() || options.photons == 0) return result;
  const uint64_t first_chunk = options.photon_begin / kChunk;
  const uint64_t chunks = (range_end + kChunk - 1) / kChunk - first_chunk;
  std::vector<ChunkOutput> outputs(chunks);
  const TraceShared shared(scene.description(), options);
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
      for (uint64_t i = (first_chunk + c) * kChunk; i < end; ++i)
        TraceOne(scene, lights, options, shared, i, out);
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
    result.rays = out.rays;
    result.rejected = out.rejected;
    result.emitted = range_end - options.photon_begin;
    result.emitted_power = lights.total_power();
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
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
      for (uint64_t i = (first_chunk + c) * kChunk; i < end; ++i)
        TraceOne(scene, lights, options, shared, i, out);
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
    result.rays += outputs[c].rays;
    result.rejected += outputs[c].rejected;
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
  result.emitted = range_end - options.photon_begin;
  result.emitted_power = lights.total_power();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace pf
