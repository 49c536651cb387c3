#pragma once
// Photon tracing: the random walk from the lights (Wald 1999, §2.2).
//
// Photons leave the emitters with probability ∝ power (stratified over the photon index, so
// each light gets its share up to ±1 photon), cosine-distributed about the emitter's front
// normal, each carrying Φ = Φ_light / (p_light · N). Punctual lights (point, spot, directional)
// emit as PhotonEmitter below says, with the same per-photon power rule; the environment
// (environment_light.h) from a disc beyond the scene's bounding sphere, its photons' power
// L(ω)·π·R²/(pdf(ω)·p_light·N). At every hit on a surface with a
// diffuse component the photon is stored; then Russian roulette on the material's reflectances picks diffuse
// / specular / glossy / transmission / absorption, scaling Φ per channel by ρ/P.
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
#include <cstdint>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/lights/light_sampler.h"
#include "common/photon/importance_map.h"
#include "common/photon/traced_photon.h"
#include "common/sampling/sampler.h"

namespace pf {

// Photons per work item of TracePhotons: fixed, so that the output order is fixed. A map traced
// in pieces (distributed tracing, photon_chunk.h) is cut at multiples of it.
inline constexpr uint64_t kPhotonTracingChunk = 4096;

enum class CausticSplitMethod : uint8_t { kBrute = 0, kMetropolis = 1 };
const char* CausticSplitMethodName(CausticSplitMethod m);

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
  // order are the whole trace's arrays (docs/farm.md, "Photon maps traced once"; distributed tracing).
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
//
// A punctual light (light_sampler.h, punctual = true) has one entry: `a` its position (a
// directional light: the centre of its disc of `radius`, beyond the scene's bounding sphere),
// `normal`/`frame` its direction, and photons distributed like its emission (uniform over the
// sphere; within a spot's cone ∝ its falloff; uniform over the directional light's disc), so each
// carries Φ/(p·N) with Φ its power.
struct PhotonEmitter {
  Vec3 a, b, c;
  Vec3 normal;
  Frame frame;
  Rgb power;
  uint32_t light = 0;
  bool punctual = false;
  PunctualLight::Kind kind = PunctualLight::Kind::kPoint;
  float cos_inner = 1, cos_outer = -1, cap_probability = 1;  // spot: cos θ sampling (photon_tracer.cpp)
  float radius = 0;                                          // directional: the disc's
  // The environment's emitter (punctual too: no surface, caustics unsplit): its photons' power
  // varies with their direction, `power` is π·R²/(p·N) to multiply by L(ω)/pdf(ω).
  const EnvironmentLight* environment = nullptr;
  // A textured emitting triangle (scene.h, Material::emission_texture): `power` is Le·π/(p·N)
  // with the untextured Le, to multiply by the texel at the photon's point (light_sampler.h).
  const Texture* emission_texture = nullptr;
  TextureCoordinates uv_a{}, uv_b{}, uv_c{};
};
std::vector<PhotonEmitter> PhotonEmitters(const SceneDescription& desc, const LightSampler& lights,
                                          uint64_t emitted);

// A photon leaving emitter `em` as TracePhotons emits it, from its point and direction numbers:
// its first ray and its power Φ. For pilots that follow a few photons and keep no map
// (caustic_reach.h in common/render).
struct PhotonLaunch {
  Ray ray;
  Rgb power;
};
PhotonLaunch LaunchPhoton(const PhotonEmitter& em, Sample2 u_point, Sample2 u_dir, float epsilon);

// Whether the scene has any singular surface a photon could bounce off before landing on a
// diffuse one. If not, no photon can ever be caustic and the caustic map is not built
// ("model only what the scene needs").
bool SceneNeedsCausticMap(const SceneDescription& scene);

PhotonTracingResult TracePhotons(const EmbreeScene& scene, const LightSampler& lights,
                                 const PhotonTracerOptions& options);

}  // namespace pf
