#include "common/plan/stop_targets.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>

#include "common/plan/task_plan.h"

namespace pf {

StopTargets JudgedTargets(const StopTargets& targets, bool unbiased) {
  if (!unbiased || targets.target_error_rms <= 0) return targets;
  StopTargets judged;
  judged.target_noise_rms = targets.target_noise_rms > 0
                                ? std::min(targets.target_noise_rms, targets.target_error_rms)
                                : targets.target_error_rms;
  return judged;
}

std::string StopTargetsProblem(const StopTargets& targets, const PlanSpec& plan, const std::string& field) {
  if (targets.target_error_rms > 0 && plan.kind != PlanKind::kProgressive)
    return field +
           ".target_error_rms: needs the progressive plan (--plan progressive), the only plan whose bias is "
           "estimated and falls as it renders; other plans stop at a noise target (--target-noise), which "
           "does not see their bias";
  if (targets.target_noise_rms > 0 && plan.kind == PlanKind::kHierarchical)
    return field +
           ".target_noise_rms: not available for the hierarchical plan (no noise estimate); use a time "
           "budget";
  return "";
}

bool StopTargetsMet(const StopTargets& targets, const ErrorEstimates& e) {
  const double noise_rms = e.noise, error_rms = e.error;
  if (!targets.any()) return false;
  if (targets.target_noise_rms > 0 && !(noise_rms >= 0 && noise_rms <= targets.target_noise_rms))
    return false;
  if (targets.target_error_rms > 0 && !(error_rms >= 0 && error_rms <= targets.target_error_rms))
    return false;
  return true;
}

std::string DescribeTargets(const StopTargets& targets, const ErrorEstimates& e) {
  const double noise_rms = e.noise, error_rms = e.error;
  const auto value = [](double v) { return v < 0 ? std::string("unknown") : fmt::format("{:.4g}", v); };
  std::string out;
  if (targets.target_error_rms > 0)
    out += fmt::format("estimated error {} (display noise {}, bias {}) {} target {:.4g}", value(error_rms),
                       value(e.display_noise), value(e.bias),
                       error_rms >= 0 && error_rms <= targets.target_error_rms ? "<=" : "above",
                       targets.target_error_rms);
  if (targets.target_noise_rms > 0)
    out += fmt::format("{}estimated noise {} {} target {:.4g}", out.empty() ? "" : "; ", value(noise_rms),
                       noise_rms >= 0 && noise_rms <= targets.target_noise_rms ? "<=" : "above",
                       targets.target_noise_rms);
  return out;
}

}  // namespace pf
