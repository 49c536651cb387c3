#include "server/scheduling/checkpoint_restore.h"

#include <memory>

#include "common/plan/hierarchical.h"

namespace pf::server {

std::vector<TaskSpec> TasksCreatedFromResults(const Job& job, const Accumulator& acc) {
  if (!acc.hierarchy()) return {};
  const JobConfig& c = job.config();
  std::vector<TaskSpec> all =
      HierarchicalTasks(c.plan, c.camera.width, c.camera.height, c.seed, *acc.hierarchy());
  if (all.size() <= job.num_tasks()) return {};
  return std::vector<TaskSpec>(all.begin() + int64_t(job.num_tasks()), all.end());
}

bool ApplyCheckpoint(const Checkpoint& cp, const CheckpointSeal& seal, Job& job, std::string* problem) {
  if (cp.job_id != job.id()) {
    *problem = "belongs to job '" + cp.job_id + "'";
    return false;
  }
  auto acc = std::make_unique<Accumulator>(Accumulator::Deserialize(cp.accumulator, &job.config().plan));
  if (acc->width() != job.config().camera.width || acc->height() != job.config().image_height()) {
    *problem = "image size differs from the job's";
    return false;
  }
  if (acc->tasks_merged() != cp.merged_task_ids.size()) {
    *problem = "accumulator holds " + std::to_string(acc->tasks_merged()) + " tasks, the list " +
               std::to_string(cp.merged_task_ids.size());
    return false;
  }
  // A dynamic plan's tasks beyond the static ones follow from the merged results (task_source.h).
  const std::vector<TaskSpec> created = TasksCreatedFromResults(job, *acc);
  for (uint64_t id : cp.merged_task_ids)
    if (id >= job.num_tasks() + created.size()) {
      *problem = "task id " + std::to_string(id) + " outside the plan";
      return false;
    }
  job.AppendTasks(created);
  job.set_accumulator(std::move(acc));
  for (uint64_t id : cp.merged_task_ids) {
    job.RecordMerge(id);
    job.MarkStored(id);
  }
  job.checkpoint_collected_seq = job.merge_seq();
  job.checkpoint_written_seq = job.merge_seq();
  job.checkpoint_seal = seal;
  return true;
}

}  // namespace pf::server
