#include "common/plan/plan_choice.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "common/core/error.h"

namespace pf {
namespace {

std::vector<uint32_t> Divisors(uint32_t n) {
  std::vector<uint32_t> d;
  for (uint32_t i = 1; i <= n; ++i)
    if (n % i == 0) d.push_back(i);
  return d;
}

// The largest divisor of n not above cap (at least 1).
uint32_t LargestDivisorAtMost(uint32_t n, uint64_t cap) {
  uint32_t best = 1;
  for (uint32_t d : Divisors(n))
    if (d <= cap) best = d;
  return best;
}

uint64_t TilesOf(int width, int height, uint32_t tile) {
  return uint64_t((width + tile - 1) / tile) * uint64_t((height + tile - 1) / tile);
}

// 64-pixel tiles (the CLI's default) unless the maps would give too few tasks for the workers.
uint32_t TileFor(int width, int height, uint32_t maps, uint32_t workers) {
  const uint64_t wanted = kAutoTasksPerWorker * workers;
  for (uint32_t tile : {64u, 32u, 16u})
    if (uint64_t(maps) * TilesOf(width, height, tile) >= wanted) return tile;
  return 16;
}

// With several workers the last map's last row of tiles is cut in half-size tiles (task_plan.h,
// tail_tile_size): the workers then finish within a small tile of each other.
PlanSpec MultipleMapsPlan(uint32_t maps, uint32_t spp_per_map, uint32_t tile, uint32_t workers) {
  PlanSpec p;
  p.kind = PlanKind::kMultipleMaps;
  p.maps = maps;
  p.samples_per_pixel = spp_per_map;
  p.tile_size = tile;
  if (workers > 1 && tile >= 32 && (tile / 2) % 16 == 0) p.tail_tile_size = tile / 2;
  return p;
}

}  // namespace

PlanChoice ChoosePlan(const PlanChoiceInput& in) {
  if (in.workers < 1) throw InputError("plan.auto.workers: must be >= 1");
  if (in.samples_per_pixel < 1) throw InputError("plan.auto.samples_per_pixel: must be >= 1");
  if (in.width < 1 || in.height < 1) throw InputError("camera: width and height must be >= 1");
  if (in.photon_map && in.photon_budget < 1)
    throw InputError("settings.photon_map.photons: the photon budget must be >= 1");
  const uint32_t n = in.workers, spp = in.samples_per_pixel;
  const uint64_t pixels = uint64_t(in.width) * uint64_t(in.height);
  const bool progressive = in.time_budget_seconds > 0 || in.target_noise_rms > 0;
  const uint64_t wanted_tasks = kAutoTasksPerWorker * n;
  PlanChoice c;

  if (!in.photon_map) {
    c.plan = MultipleMapsPlan(1, spp, TileFor(in.width, in.height, 1, n), n);
    c.reason = fmt::format(
        "path tracer: no photon map to split; one pass of {} spp in {}-pixel tiles for {} workers", spp,
        c.plan.tile_size, n);
    return c;
  }
  const uint64_t budget = in.photon_budget;
  // The noise-target rule compares maps: it needs two over every pixel.
  const uint32_t min_maps = in.target_noise_rms > 0 && spp >= 2 ? 2 : 1;

  if (in.maps_can_be_shipped) {
    // Traced once, fetched by every worker: the whole budget in as few maps as possible (the
    // denser the map, the smaller its bias, §4.4), the workers share it by tiles.
    const uint32_t maps = LargestDivisorAtMost(spp, min_maps);
    c.plan = MultipleMapsPlan(maps, spp / maps, TileFor(in.width, in.height, maps, n), n);
    c.photons_per_map = budget / maps;
    c.reason = fmt::format(
        "maps are shipped: {} map(s) of {} photons traced once and fetched by {} workers, {} spp each, "
        "{}-pixel "
        "tiles",
        maps, c.photons_per_map, n, spp / maps, c.plan.tile_size);
    return c;
  }

  // Maps are traced by every worker that renders them: cut the budget into maps the workers do
  // not share (so it is traced once in total), as far as the maps stay dense enough.
  const uint64_t s_pixels = uint64_t(std::ceil(std::sqrt(double(pixels) / double(kAutoMaxPixelsPerTask))));
  const uint64_t s_lo = std::max<uint64_t>(2, s_pixels);
  const uint64_t s_hi = std::min<uint64_t>(uint64_t(std::sqrt(double(pixels))),
                                           uint64_t(std::sqrt(double(budget / kAutoMinPhotonsPerMap))));
  if (!in.caustic_map && s_lo <= s_hi) {
    // Skipping (§4.4): at equal time its low-frequency error is 0.57× (Cornell box) and 0.71×
    // (scene8) that of multiple maps (hierarchical-equal-time.md), and every task has its own
    // map: nothing is traced twice, whatever the worker count. S = 4 as measured (and the
    // thesis's), larger only if the workers need more tasks.
    uint64_t s = std::clamp<uint64_t>(4, s_lo, s_hi);
    uint32_t rounds = 1;
    for (;;) {
      const uint64_t round_cap = budget / (s * s * kAutoMinPhotonsPerMap);
      std::vector<uint32_t> allowed;
      for (uint32_t r : Divisors(spp))
        if (r <= round_cap) allowed.push_back(r);
      if (allowed.empty()) allowed.push_back(1);
      if (progressive) {
        // Each round is a whole image: the stop rule can end the job after any of them.
        rounds = allowed.back();
      } else {
        // Fewest rounds (densest maps) that keep the workers busy.
        rounds = allowed.back();
        for (uint32_t r : allowed)
          if (s * s * r >= wanted_tasks) {
            rounds = r;
            break;
          }
      }
      if (s * s * rounds >= wanted_tasks || s >= s_hi) break;
      ++s;
    }
    c.plan.kind = PlanKind::kSkipping;
    c.plan.stride = uint32_t(s);
    c.plan.rounds = rounds;
    c.plan.samples_per_pixel = spp / rounds;
    c.photons_per_map = budget / (s * s * rounds);
    c.reason = fmt::format(
        "no caustic map: skipping S {} x {} rounds = {} maps of {} photons (budget {}), {} spp per task, {} "
        "tasks "
        "for {} workers{}",
        s, rounds, s * s * rounds, c.photons_per_map, budget, spp / rounds, s * s * rounds, n,
        progressive ? "; most rounds the budget allows, the stop rule ends it after any" : "");
    return c;
  }

  // Multiple maps: with a caustic map each map must stay dense enough for the caustics
  // (estimators.md: sparse maps lose the dim caustics; on the caustic scene skipping was 1.10×
  // multiple maps, hierarchical-equal-time.md); without one, the budget was too small to skip.
  const uint64_t min_photons = in.caustic_map ? kAutoMinCausticPhotonsPerMap : kAutoMinPhotonsPerMap;
  const uint64_t map_cap = std::max<uint64_t>(1, budget / min_photons);
  const uint64_t want_maps = progressive ? map_cap : std::min<uint64_t>(std::max(n, min_maps), map_cap);
  const uint32_t maps = LargestDivisorAtMost(spp, want_maps);
  c.plan = MultipleMapsPlan(maps, spp / maps, TileFor(in.width, in.height, maps, n), n);
  c.photons_per_map = budget / maps;
  c.reason = fmt::format(
      "{}: multiple maps, {} maps of {} photons (budget {}, >= {} per map), {} spp each, {}-pixel tiles for "
      "{} "
      "workers{}",
      in.caustic_map ? "caustic map" : "budget too small to skip", maps, c.photons_per_map, budget,
      min_photons, spp / maps, c.plan.tile_size, n,
      maps < n ? fmt::format("; {} workers share a map (traced once and fetched under --map-tracing auto)", n)
               : "");
  return c;
}

}  // namespace pf
