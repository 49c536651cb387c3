#pragma once
// The plans by name (pf render --plan; Wald 1999, §4.4-4.5; task_plan.h): a registry in the
// manner of pbrt-v4's Create(name, parameters) — each entry checks its own parameters of a
// PlanSpec (InputError naming the job's field, "plan.skipping.stride") and describes them.
// ValidatePlan and DescribePlan (task_plan.h) go through it. A new plan is an entry here, its
// expansion in task_plan.cpp (ExpandPlan, CountTasks) and its proto message (proto/convert.cpp);
// a test checks that every PlanKind has an entry (tests/common/plan_factory_test.cpp).

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/named_registry.h"
#include "common/plan/task_plan.h"

namespace pf {

struct PlanEntry {
  std::string_view name = {};  // as pf render --plan spells it: "multiple-maps"
  PlanKind kind = PlanKind::kMultipleMaps;
  // Checks the parameters this plan reads for an image of width × height (both positive).
  std::function<void(const PlanSpec&, int width, int height)> validate = nullptr;
  // One line: the plan and its parameters (DescribePlan).
  std::function<std::string(const PlanSpec&)> describe = nullptr;
  // The parameters that shape the image, as " flag=value" each, named as pf render's flags
  // (PlanRecordText: the EXR header's `plan`).
  std::function<std::string(const PlanSpec&)> record = nullptr;
};

// Every plan, in the order of pf render --plan's list (after `auto`, which chooses one of them:
// plan_choice.h).
const NamedRegistry<PlanEntry>& Plans();

// The plan called `name` (InputError listing the known names if there is none) with the
// parameters of `parameters` (its kind set), checked for an image of width × height.
PlanSpec MakePlan(std::string_view name, PlanSpec parameters, int width, int height);

}  // namespace pf
