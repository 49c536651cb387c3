#include "server/scheduling/task_source.h"

#include "common/plan/hierarchical.h"

namespace pf::server {

std::vector<TaskSpec> HierarchicalTaskSource::TasksAfterMerge(const Job& job) {
  const Accumulator* acc = job.accumulator_if_loaded();
  if (!acc || !acc->hierarchy()) return {};
  const JobConfig& c = job.config();
  uint32_t complete = 0;
  while (complete < c.plan.levels && acc->hierarchy()->LevelComplete(complete + 1)) ++complete;
  if (complete == complete_levels_) return {};
  complete_levels_ = complete;
  std::vector<TaskSpec> all =
      HierarchicalTasks(c.plan, c.camera.width, c.camera.height, c.seed, *acc->hierarchy());
  if (all.size() <= job.num_tasks()) return {};
  return std::vector<TaskSpec>(all.begin() + int64_t(job.num_tasks()), all.end());
}

std::unique_ptr<TaskSource> MakeTaskSource(const JobConfig& config) {
  if (config.plan.kind == PlanKind::kHierarchical) return std::make_unique<HierarchicalTaskSource>();
  return std::make_unique<StaticTaskSource>();
}

}  // namespace pf::server
