#pragma once
// Where a job's tasks come from (docs/farm.md, "Scheduler structure").
//
// A static plan (multiple maps, maps in turn, skipping; common/plan/task_plan.h) expands into all
// its tasks when the job is submitted (ScheduledTasks, server/jobs/job_spec.h). A dynamic plan
// creates further tasks from the results merged so far — e.g. the next level of a hierarchy
// (Wald 1999, §4.5). Both are asked the same question after every merge: "which tasks does the
// job have now that it did not have before?" The answer must be a pure, deterministic function of
// the job's configuration and its merged results (never of their order, the number of workers or
// the time), so that retries, any worker count and a coordinator restart give the same tasks.
//
// New tasks continue the job's numbering (task_id = job.num_tasks(), +1, …); the Scheduler
// appends them to the job (Job::AppendTasks) and queues them. Not thread-safe: called under the
// Scheduler's lock.

#include <functional>
#include <memory>
#include <vector>

#include "common/plan/task_plan.h"
#include "server/jobs/job.h"

namespace pf::server {

class TaskSource {
 public:
  virtual ~TaskSource() = default;
  // Tasks to add now that `job`'s merged results are what they are; usually none.
  virtual std::vector<TaskSpec> TasksAfterMerge(const Job& job) = 0;
  // The expected work (Job::task_work units) of the tasks this source has yet to create, for
  // progress and the ETA; 0 when it will create none.
  virtual uint64_t WorkToCreate(const Job&) { return 0; }
};

// The plans that expand completely at submission: nothing is ever added.
class StaticTaskSource final : public TaskSource {
 public:
  std::vector<TaskSpec> TasksAfterMerge(const Job&) override { return {}; }
};

// The hierarchical plan (§4.5; common/plan/hierarchical.h): once every level is complete, the
// localization tasks (HierarchicalTasks). Recomputed only when another level becomes complete, so
// a merge usually costs nothing here.
class HierarchicalTaskSource final : public TaskSource {
 public:
  explicit HierarchicalTaskSource(const JobConfig& config);
  std::vector<TaskSpec> TasksAfterMerge(const Job& job) override;
  // ExpectedLocalizationWork until the localization tasks exist; recomputed only when another
  // level becomes complete.
  uint64_t WorkToCreate(const Job& job) override;

 private:
  uint64_t static_tasks_;
  uint32_t complete_levels_ = ~0u;  // levels 1..n complete when last asked
  uint32_t work_levels_ = ~0u;      // … when the expected work was last computed
  uint64_t work_ = 0;
};

using TaskSourceFactory = std::function<std::unique_ptr<TaskSource>(const JobConfig&)>;

// The source for a job's plan.
std::unique_ptr<TaskSource> MakeTaskSource(const JobConfig& config);

}  // namespace pf::server
