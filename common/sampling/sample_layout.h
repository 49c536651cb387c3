#pragma once
// The dimension layout (docs/renderer.md, "Sampling and determinism"): which sampler slot
// (common/sampling/sampler.h) feeds which decision. Every decision has its own slot, so bounces, light
// samples and Russian roulette never share (and so never correlate through) one low-discrepancy sequence; a
// slot asked for several numbers per sample (shadow rays, gather rays) takes them at sub-indices j < N.
//
// Camera paths (path tracer and photon-map integrator):
//   slot 0                       pixel position (2-D)
//   vertex d < kPathVertexBudget: slots 1 + 9·d + ...
//     +0 light_stratum   1-D  MC direct light: jitter within the light-CDF stratum of ray j
//                             (j < N); PhotonDirect: within light i's stratum
//     +1 light_select    1-D  emitter triangle (path tracer: the light; MC: triangle in light)
//     +2 light_point     2-D  point on the emitter (j < N)
//     +3 light_extra     2-D  PhotonDirect: the one sample to a non-contributing light
//     +4 gather_lobe     1-D  local pass (§4.3): lobe of gather ray j (j < N_lp)
//     +5 gather_dir      2-D  local pass: direction of gather ray j
//     +6 bsdf_lobe       1-D  lobe of the path's continuation
//     +7 bsdf_dir        2-D  direction of the continuation
//     +8 roulette        1-D  Russian roulette
//   vertex d >= kPathVertexBudget: every slot is kIndependentSlot (the sample's PCG stream):
//   these vertices carry little of the error and the stream is cheaper.
//
// Photons (photon tracer, index = photon number within its map, key = map seed):
//   slot 0 light stratum jitter (1-D), 1 point on the light (2-D), 2 emission direction (2-D);
//   bounce b < kPhotonBounceBudget: 3 + 2b lobe (1-D, Russian roulette), 4 + 2b direction (2-D);
//   later bounces: kIndependentSlot.
//   Importance-driven storing (§4.7, only when on): bounce b < kPhotonBounceBudget: 3 + 2·budget + b
//   acceptance of the store at that hit (1-D); later bounces: kIndependentSlot. Slots no other
//   decision uses, so maps without importance stay bit-identical.
//
// Importons (importance map, §4.7; index = importon number, key = ImportonStreamSeed(map seed)):
//   slot 0 image position (2-D, over the whole image); bounce b < kPhotonBounceBudget: 1 + 2b lobe
//   (1-D), 2 + 2b direction (2-D); later bounces: kIndependentSlot.

#include <cstdint>

#include "common/sampling/sampler.h"

namespace pf {

inline constexpr uint32_t kPixelSlot = 0;
inline constexpr int kPathVertexBudget = 2;
// The renderer precomputes the seeds of every slot of the budget once per pixel (PixelStream).
static_assert(1 + 9 * kPathVertexBudget <= int(sobol::kPixelSeedSlots));

struct PathVertexSlots {
  uint32_t light_stratum, light_select, light_point, light_extra, gather_lobe, gather_dir, bsdf_lobe,
      bsdf_dir, roulette;
};

constexpr PathVertexSlots SlotsOfVertex(int depth) {
  if (depth < 0 || depth >= kPathVertexBudget)
    return {kIndependentSlot, kIndependentSlot, kIndependentSlot, kIndependentSlot, kIndependentSlot,
            kIndependentSlot, kIndependentSlot, kIndependentSlot, kIndependentSlot};
  const uint32_t b = 1 + 9 * uint32_t(depth);
  return {b, b + 1, b + 2, b + 3, b + 4, b + 5, b + 6, b + 7, b + 8};
}

// The renderer's pixel stream computes the slots every integrator asks first (sobol::kSlotOfLane): the pixel
// and per vertex light_select, light_point, bsdf_lobe, bsdf_dir, roulette.
static_assert(sobol::kLaneOfSlot[kPixelSlot] < sobol::kEagerLanes);
static_assert(sobol::kLaneOfSlot[SlotsOfVertex(0).light_select] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(0).light_point] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(0).bsdf_lobe] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(0).bsdf_dir] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(0).roulette] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(1).light_select] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(1).light_point] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(1).bsdf_lobe] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(1).bsdf_dir] < sobol::kEagerLanes &&
              sobol::kLaneOfSlot[SlotsOfVertex(1).roulette] < sobol::kEagerLanes);

// The 2-D slots of the budget sit in lanes whose y coordinate the pixel stream computes (the others
// would take the slower per-request path).
constexpr bool TwoDimensionalSlotsHaveY() {
  if (!sobol::LaneHasY(sobol::kLaneOfSlot[kPixelSlot])) return false;
  for (int d = 0; d < kPathVertexBudget; ++d) {
    const PathVertexSlots v = SlotsOfVertex(d);
    for (uint32_t slot : {v.light_point, v.light_extra, v.gather_dir, v.bsdf_dir})
      if (!sobol::LaneHasY(sobol::kLaneOfSlot[slot])) return false;
  }
  return true;
}
static_assert(TwoDimensionalSlotsHaveY());

inline constexpr uint32_t kPhotonLightSlot = 0, kPhotonPointSlot = 1, kPhotonDirectionSlot = 2;
inline constexpr int kPhotonBounceBudget = 8;

struct PhotonBounceSlots {
  uint32_t lobe, direction;
};
constexpr PhotonBounceSlots SlotsOfPhotonBounce(int bounce) {
  if (bounce < 0 || bounce >= kPhotonBounceBudget) return {kIndependentSlot, kIndependentSlot};
  return {3 + 2 * uint32_t(bounce), 4 + 2 * uint32_t(bounce)};
}

// Importance-driven storing (§4.7): the acceptance test of the store at photon bounce `bounce`.
constexpr uint32_t SlotOfPhotonAcceptance(int bounce) {
  if (bounce < 0 || bounce >= kPhotonBounceBudget) return kIndependentSlot;
  return 3 + 2 * uint32_t(kPhotonBounceBudget) + uint32_t(bounce);
}
static_assert(SlotOfPhotonAcceptance(0) > SlotsOfPhotonBounce(kPhotonBounceBudget - 1).direction);
// The photon lanes (sampler.h, sobol::kPhotonSlotOfLane) hold the 2-D slots in 2-D lanes.
static_assert(sobol::kPhotonLaneOfSlot[kPhotonPointSlot] < sobol::kPhotonEager2D &&
              sobol::kPhotonLaneOfSlot[kPhotonDirectionSlot] < sobol::kPhotonEager2D &&
              sobol::kPhotonLaneOfSlot[SlotsOfPhotonBounce(0).direction] < sobol::kPhotonEager2D &&
              sobol::kPhotonLaneOfSlot[SlotsOfPhotonBounce(1).direction] < sobol::kPhotonEager2D);

// Importons (importance map, §4.7), in their own streams (ImportonStreamSeed).
inline constexpr uint32_t kImportonImageSlot = 0;
constexpr PhotonBounceSlots SlotsOfImportonBounce(int bounce) {
  if (bounce < 0 || bounce >= kPhotonBounceBudget) return {kIndependentSlot, kIndependentSlot};
  return {1 + 2 * uint32_t(bounce), 2 + 2 * uint32_t(bounce)};
}

}  // namespace pf
