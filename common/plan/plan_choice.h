#pragma once
// `--plan auto`: which plan, how many maps and how many photons per map, from the scene, the
// workers, the stop rule and the photon budget (docs/farm.md, "Choosing the plan"; the rule's
// evidence is in docs/results/hierarchical-equal-time.md, estimators.md and farm.md).
//
// The budget is the total number of photons emitted over all maps of the job: Wald 1999, §4.4,
// the error of the estimate depends on the total photon count, so the plan only decides how the
// budget is cut into maps — and that decides what the farm duplicates. While maps cannot be
// shipped (every worker traces each map it renders), a plan whose maps outnumber the workers
// traces the budget once; one map rendered by N workers traces it N times (farm.md: +13 % CPU
// with 2 workers). Once maps can be shipped (traced once, fetched by the others) the rule picks
// one large map, the least biased use of the budget.
//
// Pure and deterministic: the coordinator records the chosen plan in the job, so a resumed job
// keeps it whatever the farm looks like then.

#include <cstdint>
#include <string>

#include "common/plan/task_plan.h"

namespace pf {

// The smallest map the rule cuts the budget into (hierarchical-equal-time.md: 10k photons per map
// is the smallest measured, and multiple maps' error still falls with the count there).
inline constexpr uint64_t kAutoMinPhotonsPerMap = 10000;
// With a caustic map: estimators.md's low budget (100k) — sparser maps lose the dim caustics
// (the estimate's threshold, 10 % of k within the maximum radius, §4.1).
inline constexpr uint64_t kAutoMinCausticPhotonsPerMap = 100000;
// Tasks per worker the rule aims for, so that a slow task does not leave the others idle.
inline constexpr uint64_t kAutoTasksPerWorker = 4;
// A task's result travels in one message (server/jobs/job_spec.h kMaxPixelsPerTask).
inline constexpr uint64_t kAutoMaxPixelsPerTask = uint64_t(4) << 20;

// Whether auto should plan for one large shared map, traced once and fetched by the workers
// (docs/farm.md, "Photon maps traced once"; map shipping, which exists:
// server/scheduling/distributed_maps.h). Off: per-task maps use the same photon budget with no transfer and
// no coordinator balance on the critical path (docs/farm.md, "Choosing the plan", says why and what switching
// it on changes). The coordinator and `pf render --local-only --plan auto` pass it to ChoosePlan.
inline constexpr bool kMapsCanBeShipped = false;

struct PlanChoiceInput {
  int width = 0, height = 0;
  uint64_t photon_budget = 0;      // photons over all maps (--photons with --plan auto)
  uint32_t samples_per_pixel = 1;  // camera samples per pixel over all maps
  uint32_t workers = 1;            // ≥ 1
  bool photon_map = true;          // false: the path tracer (no maps at all)
  bool caustic_map = false;        // the job builds a caustic map (the scene has caustic paths)
  double time_budget_seconds = 0;  // the stop rule: 0 = none
  double target_noise_rms = 0;     // 0 = none
  // One map traced once and fetched by every worker (docs/farm.md, "Photon maps traced once"; map shipping).
  // False today.
  bool maps_can_be_shipped = false;
};

struct PlanChoice {
  PlanSpec plan;
  uint64_t photons_per_map = 0;  // 0 for the path tracer
  std::string reason;            // one line, with the numbers
};

// Throws InputError naming the field ("plan.auto.workers: ...") for an input it cannot serve.
PlanChoice ChoosePlan(const PlanChoiceInput& in);

}  // namespace pf
