#pragma once
// Photon tracing: the random walk from the lights (Wald 1999, §2.2).
//
// Photons leave the emitters with probability ∝ power (stratified over the photon index, so
// each light gets its share up to ±1 photon), cosine-distributed about the emitter's front
// normal, each carrying Φ = Φ_light / (p_light · N). At every hit on a surface with a diffuse
// component the photon is stored; then Russian roulette on the material's reflectances picks
// diffuse / specular / glossy / transmission / absorption, scaling Φ per channel by ρ/P.
//
// Classification (§2.1, the thesis's definition of caustic paths L (S|D)* S+ D): a stored
// photon is *caustic* if every interaction since the last diffuse one was singular (and there
// was at least one); *direct* if it is the first hit after leaving the light; otherwise
// *indirect* (global/diffuse map). Direct photons are kept apart so that estimators can exclude
// them (separate direct light, §4.2) or use them (PhotonDirect, §4.2.3).
//
// Importance-driven storing (Wald 1999, §4.7; importance_map.h): with an importance map, a
// diffuse hit is stored with probability p(x) and power Φ/p(x), decided by the sampler's
// acceptance slot of that bounce; a rejected photon is not stored but *continues its walk
// unchanged*. Only the storage is thinned: the walk (and so every later hit's expected power) is
// exactly the walk without importance, and each store is unbiased on its own. Ending the walk at
// a rejection would need the continuing photon's power scaled by 1/p as well (Russian roulette
// on the path), which carries the heavy photons of unimportant regions into the important ones
// (the light that reaches INVISIBLEDATE's viewed room bounces in the lit room first): noise
// exactly where the image needs none.
//
// Caustic splitting (Wald 1999, §4.6), S = caustic_split > 1:
//  * brute force (§4.6.1): map photon i stands for the S emitted photons i·S + j (j < S) of an
//    S·N-photon trace (their own sampler indices, light strata and power Φ/(S·N)). Every caustic
//    store is kept; the non-caustic (direct and global) stores are kept for exactly one of the S,
//    j* uniform from Rng(map seed, i), at S× the power: each emitted photon's are kept with
//    probability 1/S, so the global map is unbiased and has the size of an N-photon map, and the
//    caustic map has S× the photons.
//  * Metropolis (§4.6.2): N photons; each singular chain (a start — the light, or a Lambertian
//    diffuse bounce — followed by ≥ 1 singular delta bounces until the walk chooses a
//    non-singular lobe or leaves the scene) is mutated S − 1 times by an exponential jitter of
//    its start direction; a mutation is traced along the same characteristic (the same lobe
//    types) and accepted with the Metropolis–Hastings ratio of pdf(ω)·P(characteristic | ω);
//    each of the S states stores its caustic photons with power × (its weight)/S. Why that is
//    unbiased and what remains: docs/renderer.md, "Caustic splitting".
// Map photon i's arrays are still a function of (map seed, i) alone, so pieces assemble exactly.
//
// Determinism: photon i draws from Sampler::ForPhoton(sampler, map_seed, i) (index i of the map's
// scrambled sequences, common/sampling/sample_layout.h); photons are traced in
// fixed-size chunks in parallel and concatenated in chunk order, so the arrays are identical
// for any thread count.

#include <atomic>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <type_traits>
#include <utility>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/lights/light_sampler.h"
#include "common/photon/importance_map.h"
#include "common/sampling/sampler.h"

namespace pf {

enum class PhotonKind : uint8_t { kDirect = 0, kIndirect = 1, kCaustic = 2 };

// Full-precision photon as traced; compressed to the 18-byte Photon when put in a map.
struct TracedPhoton {
  Vec3 position;
  Vec3 direction;      // unit, pointing back towards where the photon came from (ω in §2.2)
  Rgb power;           // Φ, W
  Vec3 origin;         // previous vertex of the path (occlusion testing, §4.1.1)
  uint32_t light = 0;  // emitting light id (PhotonDirect, §4.2.3)
  PhotonKind kind = PhotonKind::kIndirect;
  // Explicit, zero-initialised padding: arrays of equal photons are equal byte for byte however
  // each photon was made (aggregate, copy or AppendPhoton), so tests can compare them with memcmp.
  uint8_t pad[3] = {};
};

// An allocator whose value-initialising construct() does nothing, for arrays that are sized
// first and then filled in parallel: std::vector::resize would otherwise zero them in one serial
// pass (~35 ms for the 1.5M photons of the default map, 7 % of its 1-thread tracing time, which
// alone would cap two threads at 1.87x). Only for implicit-lifetime, trivially copyable types,
// whose objects the copy that fills the memory creates.
template <typename T>
struct UninitializedAllocator : std::allocator<T> {
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);
  template <typename U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <typename U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
  template <typename U>
  void construct(U*) noexcept {}
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

using TracedPhotons = std::vector<TracedPhoton, UninitializedAllocator<TracedPhoton>>;

// Appends a traced photon (§2.2) by writing its fields straight into the array's memory
// (UninitializedAllocator: emplace_back() leaves it unwritten) instead of copying a temporary
// built on the stack: the copy's 16-byte loads of the temporary's 12- and 4-byte stores stalled
// on store forwarding at every stored photon (docs/results/kernel.md §4). The light id, the kind
// and the 3 bytes of TracedPhoton::pad are one 8-byte store, the pad zero as in every other
// TracedPhoton, so that equal arrays are equal byte for byte (the tracer's memcmp test).
static_assert(offsetof(TracedPhoton, kind) == offsetof(TracedPhoton, light) + 4 &&
              sizeof(TracedPhoton) == offsetof(TracedPhoton, light) + 8 &&
              std::endian::native == std::endian::little);
inline void AppendPhoton(TracedPhotons& list, const Vec3& position, const Vec3& direction, const Rgb& power,
                         const Vec3& origin, uint32_t light, PhotonKind kind) {
  TracedPhoton& p = list.emplace_back();
  p.position = position;
  p.direction = direction;
  p.power = power;
  p.origin = origin;
  const uint64_t tail = uint64_t(light) | uint64_t(kind) << 32;
  std::memcpy(reinterpret_cast<unsigned char*>(&p) + offsetof(TracedPhoton, light), &tail, sizeof tail);
}

// Photons per work item of TracePhotons: fixed, so that the output order is fixed. A map traced
// in pieces (distributed tracing, photon_chunk.h) is cut at multiples of it.
inline constexpr uint64_t kPhotonTracingChunk = 4096;

enum class CausticSplitMethod : uint8_t { kBrute = 0, kMetropolis = 1 };
const char* CausticSplitMethodName(CausticSplitMethod m);

// Metropolis splitting's jitter of the start direction (§4.6.2, "an exponential distribution"):
// the angle between the old and the new direction is θ_max·(θ_min/θ_max)^u, u uniform, about a
// uniform azimuth — a symmetric proposal (its density depends only on the angle). Wide enough that
// a chain's states spread beyond one estimate's k-nearest disk (with 0.001-0.1 rad they piled up:
// k photons then hold only ~k/S independent chains; docs/results/caustic_splitting.md).
inline constexpr float kMetropolisJitterMin = 0.01f, kMetropolisJitterMax = 0.5f;  // radians

struct PhotonTracerOptions {
  uint64_t photons = 100000;  // emitted photons (not stored ones)
  uint64_t map_seed = 1;
  int max_bounces = 64;                       // safety cap; Russian roulette ends walks long before
  int threads = 0;                            // 0 = all cores
  SamplerKind sampler = SamplerKind::kSobol;  // quasi-random emission and scattering (§2.2)
  // Checked before each chunk of photons; once set, TracePhotons throws Cancelled.
  const std::atomic<bool>* cancel = nullptr;
  // Trace only the photons [photon_begin, photon_end) of the map's `photons` (photon_end 0 = all):
  // a piece of the map, the same photons as in a whole trace. photon_begin must be a multiple of
  // kPhotonTracingChunk (std::invalid_argument otherwise), so that the pieces concatenated in
  // order are the whole trace's arrays (issue #12, distributed tracing).
  uint64_t photon_begin = 0, photon_end = 0;
  // Importance-driven storing (§4.7); null = store every diffuse hit. Must outlive the call.
  const ImportanceMap* importance = nullptr;
  // Caustic splitting (§4.6): S = 1 is off (bit-identical to no splitting). With brute force,
  // `photons` stays N (the map's photon indices) and S·N photons are emitted; photon_begin/end
  // count map photons. Metropolis cannot be combined with `importance` (std::invalid_argument).
  uint32_t caustic_split = 1;
  CausticSplitMethod caustic_split_method = CausticSplitMethod::kBrute;
};

struct PhotonTracingResult {
  TracedPhotons direct, indirect, caustic;
  uint64_t emitted = 0;  // photons leaving the lights (S·N with brute-force splitting)
  uint64_t rays = 0;
  uint64_t rejected = 0;  // diffuse hits not stored by the importance test (§4.7)
  // Metropolis splitting (§4.6.2): singular chains split, mutations tried and accepted.
  uint64_t chains = 0, mutations = 0, accepted = 0;
  Rgb emitted_power;  // Σ Φ of emitted photons (== total light power)
  double seconds = 0;

  Rgb StoredPower() const;  // Σ Φ over all stored photons
};

// Per emitting triangle (LightSampler::EmitterIndex's numbering), what every photon leaving it
// shares: the vertices its point is sampled between, the emission frame (the cosine lobe, §2.2),
// and Φ of one photon of `emitted` — what LightSampler::Sample and the power formula give per
// photon (test PhotonTracer.EmissionIsTheLightSamplersSample), computed once per trace.
struct PhotonEmitter {
  Vec3 a, b, c;
  Vec3 normal;
  Frame frame;
  Rgb power;
  uint32_t light = 0;
};
std::vector<PhotonEmitter> PhotonEmitters(const SceneDescription& desc, const LightSampler& lights,
                                          uint64_t emitted);

// Whether the scene has any singular surface a photon could bounce off before landing on a
// diffuse one. If not, no photon can ever be caustic and the caustic map is not built
// ("model only what the scene needs").
bool SceneNeedsCausticMap(const SceneDescription& scene);

PhotonTracingResult TracePhotons(const EmbreeScene& scene, const LightSampler& lights,
                                 const PhotonTracerOptions& options);

}  // namespace pf
