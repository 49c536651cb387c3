#include "server/scheduling/job_submission.h"

#include <spdlog/spdlog.h>

#include <memory>
#include <utility>

#include "common/plan/task_plan.h"

namespace pf::server {

JobRow QueuedJobRow(const Job& job) {
  JobRow row;
  row.job_id = job.id();
  row.seq = job.seq();
  row.spec = job.config().spec.SerializeAsString();
  row.state = JobState::kQueued;
  row.submitted_unix_ms = job.submitted_unix_ms();
  return row;
}

std::string SubmitValidatedJob(Scheduler& scheduler, JobStore& db, JobConfig config,
                               const std::string& client) {
  std::unique_ptr<Job> job = scheduler.PrepareJob(std::move(config));
  job->client = client;
  const JobRow row = QueuedJobRow(*job);
  db.InsertJob(row, {});  // durable before the client hears the id
  const JobConfig& c = job->config();
  spdlog::info("job {}: submitted{}: scene {}, {}x{}, {}, {} tasks, seed {}, priority {}", job->id(),
               c.name.empty() ? "" : " '" + c.name + "'", c.scene_hash.substr(0, 12), c.camera.width,
               c.camera.height, DescribePlan(c.plan), job->num_tasks(), c.seed, c.priority);
  for (const AutoChoice& a : c.auto_choices)
    spdlog::info("job {}: auto {} = {}: {}", job->id(), a.setting, a.value, a.reason);
  if (c.spec.plan().has_chosen_by_auto())
    spdlog::info("job {}: plan auto: {}", job->id(), c.spec.plan().chosen_by_auto().reason());
  std::string id = job->id();
  scheduler.AddJob(std::move(job));
  return id;
}

}  // namespace pf::server
