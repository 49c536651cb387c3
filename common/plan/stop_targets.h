#pragma once
// When a job's image is good enough (docs/farm.md "Stop rules"): the targets a render stops at,
// judged the same way by the coordinator (server/scheduling/stop_rules.h) and by a render in one
// process (RenderPlanLocally), from the Accumulator's estimates.
//
//  target noise   the per-map noise estimate (Accumulator::EstimatedNoiseRms), which cannot see
//                 the photon map's bias: a plan of maps of a fixed size meets it while its image
//                 stays as biased as one map.
//  target error   √(noise² + bias²) (Accumulator::Estimates().error) with the progressive plan's
//                 bias indicator (progressive_bias.h): the progressive plan only, the one whose
//                 bias falls with its passes and can be estimated from them.

#include <cstdint>
#include <string>

#include "common/plan/error_estimates.h"

namespace pf {

struct PlanSpec;

struct StopTargets {
  double target_noise_rms = 0;  // 0 = none
  double target_error_rms = 0;  // 0 = none
  bool any() const { return target_noise_rms > 0 || target_error_rms > 0; }
};

// An unbounded progressive job (--time-budget or --target-error and no --passes) is planned with
// this many passes: its stop rule ends it long before (at 1024 passes of 200k photons the
// estimate's radius is 0.10 of the first, and the noise 1/100 of one pass's).
inline constexpr uint32_t kOpenEndedPasses = 1024;
// Samples per pixel of each pass of a progressive render that its budget chose (no --spp): with
// fewer per pass, more passes fit the budget and the last radius is smaller. At 60 s, 4 instead of
// 16 lowered all three errors on CornellBox-Sphere and INVISIBLEDATE by 5-23 %; 1 traced so many
// maps that the noise rose (docs/results/time-budget.md).
inline constexpr uint32_t kBudgetPassSamples = 4;

// The targets as judged: an unbiased integrator's (the path tracer's) error is its noise, so its
// target error becomes a target noise of the same value, for any plan.
StopTargets JudgedTargets(const StopTargets& targets, bool unbiased);

// "" if the (judged) targets can be judged for `plan`; else the problem, naming `field` (e.g.
// "spec.stop.target_error_rms: needs the progressive plan ...").
std::string StopTargetsProblem(const StopTargets& targets, const PlanSpec& plan, const std::string& field);

// Whether the estimates meet every target that is set (false while one they need is unknown, < 0).
bool StopTargetsMet(const StopTargets& targets, const ErrorEstimates& estimates);

// One line for a log or a job's status: what was reached or missed, with the estimates.
std::string DescribeTargets(const StopTargets& targets, const ErrorEstimates& estimates);

}  // namespace pf
