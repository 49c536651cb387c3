#pragma once
// Metropolis caustic splitting (Wald 1999, §4.6.2): a singular chain of a photon walk (a start —
// the light, or a Lambertian diffuse bounce — then ≥ 1 singular bounces) is mutated S − 1 times by
// an exponential jitter of its start direction, each mutation traced along the same
// characteristic and accepted with the Metropolis–Hastings ratio; each of the S states stores the
// chain's caustic photons with power × (its weight)/S. Why that is unbiased and what remains:
// docs/renderer.md, "Caustic splitting". The photon tracer (photon_tracer.h) walks the photons and
// hands each chain here when it ends.

#include <cstdint>
#include <optional>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/core/math.h"
#include "common/core/rng.h"
#include "common/materials/bsdf.h"
#include "common/photon/traced_photon.h"

namespace pf {

// Metropolis splitting's jitter of the start direction (§4.6.2, "an exponential distribution"):
// the angle between the old and the new direction is θ_max·(θ_min/θ_max)^u, u uniform, about a
// uniform azimuth — a symmetric proposal (its density depends only on the angle). Wide enough that
// a chain's states spread beyond one estimate's k-nearest disk (with 0.001-0.1 rad they piled up:
// k photons then hold only ~k/S independent chains; docs/results/caustic_splitting.md).
inline constexpr float kMetropolisJitterMin = 0.01f, kMetropolisJitterMax = 0.5f;  // radians

// The lobes that continue a singular chain.
inline constexpr uint32_t kSingularLobes =
    kLobeGlossyReflection | kLobeSpecularReflection | kLobeSpecularTransmission | kLobeGlossyTransmission;

// Where a singular chain starts (Wald 1999, §4.6.2): the light, or a Lambertian diffuse bounce.
// Its direction ω was drawn with a density ∝ max(0, ω·axis) on the side `side` (emission: the
// light's normal; a bounce: the Bsdf's lobe axis, sidedness against the geometric normal).
struct ChainStart {
  Vec3 ray_origin_light;          // the light's offset origin (emission only)
  std::optional<SurfaceHit> hit;  // the bounce's hit (nullopt: emission)
  std::optional<Bsdf> bsdf;       // the bounce's Bsdf, for the diffuse weight at a new ω
  Vec3 wo, axis, side;
  Rgb power;             // emission: Φ leaving the light; bounce: Φ arriving (before the diffuse weight)
  Rgb diffuse_roulette;  // bounce: 1/P(diffuse lobe) (the RR selection, constant in ω)
  Vec3 direction;        // ω of the original walk
};

// What a chain did after its start: the characteristic (singular lobes at h1..h_{n-1}), how it
// ended (escaped after the last singular lobe, or a non-singular choice at h_n), its probability
// factor Q = Π P(lobe k) · P(end), and its caustic stores (at h2..hn).
struct ChainState {
  std::vector<uint32_t> lobes;
  bool escaped = false;
  bool splittable = true;  // no glossy lobe (not a function of ω alone) and no cap reached
  double q = 1.0;
  Vec3 direction;
  std::vector<TracedPhoton> stores;
};

// The chain a Metropolis photon walk is in, if any (§4.6.2; ChunkOutput::metropolis_walk).
struct MetropolisWalk {
  std::optional<ChainStart> chain;
  ChainState state;
  std::optional<Rng> mutations;
};

// What splitting adds to a chunk of the trace besides its caustic stores.
struct MetropolisCounts {
  uint64_t rays = 0;  // traced by the mutations
  uint64_t chains = 0, mutations = 0, accepted = 0;
};

// Appends `stores` to `caustic` with their power scaled by `scale`.
void StoreWeighted(const std::vector<TracedPhoton>& stores, float scale, TracedPhotons& caustic);

// Splits the chain that started at `c` and walked `original` (moved from) into `split` states,
// drawing the mutations from `rng`, and appends their weighted caustic stores (light id `light`).
void SplitChain(const EmbreeScene& scene, const ChainStart& c, ChainState& original, uint32_t split,
                uint32_t light, Rng& rng, TracedPhotons& caustic, MetropolisCounts& counts);

}  // namespace pf
