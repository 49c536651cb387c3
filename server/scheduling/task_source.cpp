#include "server/scheduling/task_source.h"

#include "common/plan/hierarchical.h"

namespace pf::server {

namespace {

// Levels 1..n are complete (0 without an accumulator).
uint32_t CompleteLevels(const Job& job) {
  const Accumulator* acc = job.accumulator_if_loaded();
  if (!acc || !acc->hierarchy()) return 0;
  uint32_t complete = 0;
  while (complete < job.config().plan.levels && acc->hierarchy()->LevelComplete(complete + 1)) ++complete;
  return complete;
}

}  // namespace

HierarchicalTaskSource::HierarchicalTaskSource(const JobConfig& c)
    : static_tasks_(CountHierarchicalStaticTasks(c.plan, c.camera.width, c.camera.height)) {}

uint64_t HierarchicalTaskSource::WorkToCreate(const Job& job) {
  if (job.num_tasks() > static_tasks_) return 0;  // created
  const uint32_t complete = CompleteLevels(job);
  if (complete != work_levels_) {
    work_levels_ = complete;
    const JobConfig& c = job.config();
    const Accumulator* acc = job.accumulator_if_loaded();
    const uint64_t photons = c.settings.integrator == IntegratorKind::kPhotonMap ? c.settings.photons : 0;
    work_ = ExpectedLocalizationWork(c.plan, c.camera.width, c.camera.height, photons,
                                     acc ? acc->hierarchy() : nullptr);
  }
  return work_;
}

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
  if (config.plan.kind == PlanKind::kHierarchical) return std::make_unique<HierarchicalTaskSource>(config);
  return std::make_unique<StaticTaskSource>();
}

}  // namespace pf::server
