#include "server/scheduling/job_requeue.h"

#include <google/protobuf/util/message_differencer.h>
#include <spdlog/spdlog.h>

#include <optional>
#include <tuple>
#include <utility>
#include <vector>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/errors.h"
#include "server/scheduling/checkpoint_restore.h"
#include "server/scheduling/job_submission.h"
#include "server/store/checkpoint.h"
#include "server/store/persister.h"

namespace pf::server {
namespace v1 = photonfarm::v1;
namespace fs = std::filesystem;

namespace {

// What a task renders: everything but its id.
bool SameWork(const TaskSpec& a, const TaskSpec& b) {
  const PixelSubset& p = a.pixels;
  const PixelSubset& q = b.pixels;
  return std::tie(a.round, a.map_index, a.map_seed, a.pixel_seed, a.sample_begin, a.sample_end, a.part,
                  a.progressive) == std::tie(b.round, b.map_index, b.map_seed, b.pixel_seed, b.sample_begin,
                                             b.sample_end, b.part, b.progressive) &&
         std::tie(p.kind, p.x0, p.y0, p.x1, p.y1, p.permutation_seed, p.offset, p.stride, p.level, p.levels,
                  p.dims, p.list) == std::tie(q.kind, q.x0, q.y0, q.x1, q.y1, q.permutation_seed, q.offset,
                                              q.stride, q.level, q.levels, q.dims, q.list);
}

bool Equal(const google::protobuf::Message& a, const google::protobuf::Message& b) {
  return google::protobuf::util::MessageDifferencer::Equals(a, b);
}

// The finished job's checkpoint if the new job may start from it (nullopt: it renders everything,
// and the warning says why).
std::optional<Checkpoint> CarriedResults(const Scheduler::FinishedJob& source, const Job& job) {
  if (source.tasks_done == 0) return std::nullopt;
  const std::string& id = source.job_id;
  if (source.seal.tasks < source.tasks_done)
    throw UnavailableError("job_id: job " + limits::Quote(id) +
                           ": its final results are still being written to disk; try again in a moment");
  const v1::JobSpec& before = source.config->spec;
  const v1::JobSpec& now = job.config().spec;
  if (before.plan().build() != now.plan().build()) {
    spdlog::warn(
        "job {}: requeue of job {} carries none of its results: they were rendered by build {}, this "
        "coordinator is {} (an image never mixes builds)",
        job.id(), id, before.plan().build(), now.plan().build());
    return std::nullopt;
  }
  if (before.scene_hash() != now.scene_hash() || before.seed() != now.seed() ||
      !Equal(before.settings(), now.settings()) || !Equal(before.camera(), now.camera()) ||
      !Equal(before.animation(), now.animation())) {
    spdlog::warn(
        "job {}: requeue of job {} carries none of its results: its settings validate differently now",
        job.id(), id);
    return std::nullopt;
  }
  std::optional<Checkpoint> cp;
  bool unreadable = false;
  const std::string problem = VerifyCheckpointFile(source.checkpoint_path, source.seal, &cp, &unreadable);
  if (unreadable) throw UnavailableError("job_id: job " + limits::Quote(id) + ": its checkpoint " + problem);
  if (!problem.empty() || !cp) {
    spdlog::warn("job {}: requeue of job {} carries none of its results: its checkpoint {}", job.id(), id,
                 problem.empty() ? "is missing" : problem);
    return std::nullopt;
  }
  // Each carried task must be the new plan's task of the same id. Ids beyond the static tasks
  // were created from merged results (the hierarchical plan's), which the same settings create alike.
  const std::vector<TaskSpec> planned = ScheduledTasks(*source.config);
  for (uint64_t t : cp->merged_task_ids)
    if (t < planned.size() && (t >= job.num_tasks() || !SameWork(planned[t], job.task(t)))) {
      spdlog::warn("job {}: requeue of job {} carries none of its results: its task {} is not the new plan's",
                   job.id(), id, t);
      return std::nullopt;
    }
  return cp;
}

}  // namespace

v1::JobSpec RequeuedSpec(const Scheduler::FinishedJob& source, uint32_t extend_to, const v1::StopRule* stop) {
  v1::JobSpec spec = source.config->spec;
  spec.set_requeued_from(source.job_id);
  spec.clear_after();  // a requeue is asked for now: what the job waited for has ended
  if (stop) *spec.mutable_stop() = *stop;
  if (extend_to == 0) return spec;
  v1::Plan& plan = *spec.mutable_plan();
  uint32_t length = 0;
  const char* unit = "";
  switch (plan.kind_case()) {
    case v1::Plan::kProgressive:
      length = plan.progressive().passes();
      unit = "passes";
      if (extend_to >= length) plan.mutable_progressive()->set_passes(extend_to);
      break;
    case v1::Plan::kMultipleMaps:
      if (plan.multiple_maps().tail_tile_size() != 0)
        throw InputError(
            "extend_to: the job's last map ends in tail tiles (plan.multiple_maps.tail_tile_size), so its "
            "tasks are not those of an inner map and more maps cannot continue it; requeue with extend_to 0");
      length = plan.multiple_maps().maps();
      unit = "maps";
      if (extend_to >= length) plan.mutable_multiple_maps()->set_maps(extend_to);
      break;
    case v1::Plan::kSkipping:
      length = plan.skipping().rounds();
      unit = "rounds";
      if (extend_to >= length) plan.mutable_skipping()->set_rounds(extend_to);
      break;
    default:
      throw InputError(
          "extend_to: only a progressive, multiple-maps or skipping plan can be made longer (passes, maps, "
          "rounds); requeue this job with extend_to 0");
  }
  if (extend_to < length)
    throw InputError("extend_to: " + std::to_string(extend_to) + " is fewer than the job's " +
                     std::to_string(length) + " " + unit);
  return spec;
}

RequeuedJob RequeueValidatedJob(Scheduler& scheduler, JobStore& db, const fs::path& checkpoint_dir,
                                const Scheduler::FinishedJob& source, JobConfig config,
                                const std::string& client) {
  std::unique_ptr<Job> job = scheduler.PrepareJob(std::move(config));
  job->client = client;
  std::optional<Checkpoint> carried = CarriedResults(source, *job);
  if (carried) {
    carried->job_id = job->id();
    carried->epoch = 0;
    carried->merge_seq = carried->merged_task_ids.size();
    std::string problem;
    if (!ApplyCheckpoint(*carried, CheckpointSeal{}, *job, &problem)) {
      spdlog::warn("job {}: requeue of job {} carries none of its results: its checkpoint {}", job->id(),
                   source.job_id, problem);
      carried.reset();
    }
  }
  if (job->count(TaskState::kQueued) == 0)
    throw PreconditionError("job_id: job " + limits::Quote(source.job_id) +
                            " merged every task of its plan; requeue it with extend_to (more passes, maps or "
                            "rounds) to continue it");
  JobRow row = QueuedJobRow(*job);
  std::vector<TaskRow> done_rows;
  const uint64_t tasks_carried = carried ? carried->merged_task_ids.size() : 0;
  if (carried) {
    // The new job's own checkpoint, before its row: recovery reads the row's seal against it.
    const fs::path file = Persister::CheckpointFile(checkpoint_dir, job->id());
    job->checkpoint_seal = WriteCheckpointFile(file, *carried);
    job->checkpoint_path = file.string();
    row.checkpoint = job->checkpoint_seal;
    done_rows.reserve(tasks_carried);
    for (uint64_t t : carried->merged_task_ids) {
      TaskRow& done = done_rows.emplace_back();
      done.job_id = job->id();
      done.task_id = t;
      done.state = TaskState::kDone;
    }
  }
  try {
    db.InsertJob(row, done_rows);  // durable before the client hears the id
  } catch (...) {
    // No row names the checkpoint: it must not stay behind as an orphan of a lost job table.
    std::error_code ec;
    if (carried) fs::remove(job->checkpoint_path, ec);
    throw;
  }
  job->dirty_tasks.clear();  // their rows are the ones just written
  const JobConfig& c = job->config();
  spdlog::info("job {}: requeued from job {} ({}): {}, {} tasks, {} carried, {} to render", job->id(),
               source.job_id, JobStateName(source.state), DescribePlan(c.plan), job->num_tasks(),
               tasks_carried, job->count(TaskState::kQueued));
  RequeuedJob out{job->id(), tasks_carried};
  // Workers convicted of a wrong result of the finished job stay off the new one (AddJob
  // blocklists them before it serves any worker).
  if (carried) job->convicted_workers = carried->convicted;
  scheduler.AddJob(std::move(job));
  return out;
}

}  // namespace pf::server
