#pragma once
// The radius schedule of progressive photon mapping in Knaus & Zwicker's form (2011, §4.3, eq. 13;
// docs/renderer.md, "Progressive plan"): pass i (1-based in the paper) estimates with the global
// radius r_{i+1}² = r_i² (i + α)/(i + 1), so with 0-based pass p
//
//     r_p² = r_1² ∏_{i=1}^{p} (i + α)/(i + 1),          0 < α < 1,
//
// a function of the pass index alone: any worker renders any pass, and the image is the plain
// average of the passes (the farm's merge, accumulator.h). r_p² falls like p^(α−1), so the bias
// (∝ r²) vanishes while the variance of the average still falls like p^−α (Knaus & Zwicker, §4.2).

#include <cstdint>
#include <string_view>

#include "common/core/math.h"

namespace pf {

struct JobRenderSettings;

// The schedule's α. Knaus & Zwicker recommend 2/3 (§5: it balances the rates of the noise and of
// the bias of a disk on a flat surface, ∝ r²). A disk that crosses a wall's edge or a corner is
// biased like r, and that bias falls at the rate of the noise with α = 1/2. Measured: on the Cornell
// scenes from 8 to 512 passes, better at many passes and within 4 % at few; under 10 s and 60 s
// budgets on every scene with a reference the photon map is chosen for, better or within 0.1 % in 29
// of 30 cells and 2.4 % worse in one (docs/results/progressive-photon-mapping.md, "α = 1/2").
inline constexpr double kDefaultProgressiveAlpha = 0.5;
// What a progressive photon-map job stored before α was written into every stored spec meant by
// leaving it unset: the default of the time (server/scheduling/recovery.cpp). Finished jobs are
// never rewritten, so this reading stays for good.
inline constexpr double kStoredJobsUnsetProgressiveAlpha = 2.0 / 3.0;

// The settings only the progressive plan's tasks read (progressive-alpha, progressive-radius) start
// with this: with any other plan they do nothing, so pf refuses them and the coordinator warns.
inline constexpr std::string_view kProgressiveSettingPrefix = "progressive-";

// r_p² / r_1² for 0-based pass p (the product above, in double).
double ProgressiveRadiusFactor2(double alpha, uint64_t pass);

// The initial radius when none is given: the disk that holds about k photons of a map of
// `photons` emitted photons, if they were spread evenly over the surface of the scene's bounding
// box (area A = 2(xy + yz + zx)): π r_1² · photons / A = k. Photons land unevenly and a map stores
// several bounces of each, so where photons are found the disk holds more (2.3 k on the Cornell
// box, 10 k in office3: docs/results/progressive-photon-mapping.md); r_1 only sets where the
// schedule starts, the estimate is consistent for any r_1.
double DerivedInitialRadius(const Bounds3& scene_bounds, uint64_t photons, int k);

// Pass p's radius for these (resolved) settings and scene: progressive_radius, or the derived one
// when it is 0, scaled by the schedule.
float ProgressivePassRadius(const JobRenderSettings& settings, const Bounds3& scene_bounds, uint64_t pass);

}  // namespace pf
