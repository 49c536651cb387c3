// Scheduler, part: the persistence hand-off — the PersistSource the persister calls
// (server/store/persist_source.h; docs/farm.md, "Durability").
#include <spdlog/spdlog.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/scheduling/scheduler.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

// Released task lists at least this long are worth a malloc_trim (it walks the whole heap).
constexpr uint64_t kReturnMemoryAfterTasks = 1 << 16;

void ReturnFreedMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Persistence

std::vector<Checkpoint> Scheduler::CollectCheckpoints(bool due) {
  std::vector<Checkpoint> out;
  // One job at a time under its image_mu (the global lock only for O(1) bookkeeping): free what
  // is on disk, the final noise estimate of a finished job, checkpoints.
  std::vector<std::shared_ptr<Job>> loaded;  // shared: a job deleted meanwhile stays valid here
  {
    std::lock_guard lock(mu_);
    for (Job* job : jobs_.InSubmissionOrder())
      if (job->accumulator_if_loaded()) loaded.push_back(jobs_.Shared(job->id()));
  }
  for (const std::shared_ptr<Job>& job : loaded) {
    std::lock_guard image(job->image_mu);
    bool final_noise = false, checkpoint = false;
    Checkpoint cp;
    {
      std::lock_guard lock(mu_);
      if (!job->accumulator_if_loaded()) continue;
      final_noise = !job->active() && job->noise_checked_seq != job->merge_seq();
      checkpoint = job->merge_seq() > job->checkpoint_collected_seq &&
                   (due || !job->active() || job->checkpoint_retry);
      if (checkpoint) {
        cp.job_id = job->id();
        cp.merge_seq = job->merge_seq();
        cp.epoch = job->epoch();
        // With the epoch, so that a restart's checkpoint stored without its row brings back who
        // was convicted as well (recovery.cpp).
        cp.convicted = job->convicted_workers;
        cp.merged_task_ids = job->MergedTaskIds();
        job->checkpoint_collected_seq = job->merge_seq();
        job->checkpoint_retry = false;
      }
    }
    const Accumulator& acc = *job->accumulator_if_loaded();
    if (final_noise) {
      const ErrorEstimates estimates = acc.Estimates();
      std::lock_guard lock(mu_);
      job->SetNoise(estimates, clock_.Now());
      job->row_dirty = true;
    }
    if (checkpoint) {
      cp.accumulator = acc.Serialize();
      out.push_back(std::move(cp));
    }
    // A job that ended after its last checkpoint was stored (e.g. cancelled) frees its image now.
    std::lock_guard lock(mu_);
    if (!job->active()) job->ReleaseAccumulator(job->checkpoint_path);
  }
  return out;
}

void Scheduler::CheckpointStored(const Checkpoint& cp, const CheckpointSeal& seal, const std::string& path) {
  std::shared_ptr<Job> job;
  {
    std::lock_guard lock(mu_);
    if (jobs_.Find(cp.job_id)) job = jobs_.Shared(cp.job_id);
  }
  if (!job) return;
  Effects fx;
  {
    std::lock_guard image(job->image_mu);  // freeing the accumulator changes it
    std::lock_guard lock(mu_);
    if (cp.merge_seq < job->checkpoint_written_seq) return;
    job->checkpoint_written_seq = cp.merge_seq;
    job->checkpoint_seal = seal;
    job->checkpoint_path = path;
    job->row_dirty = true;  // the row carries the seal
    for (uint64_t id : cp.merged_task_ids)
      if (id < job->num_tasks()) job->MarkStored(id);
    if (!job->results_storage_error.empty()) fx.changed.insert(job->id());
    job->results_storage_error.clear();
    if (job->paused_for_storage) {
      job->paused_for_storage = false;
      spdlog::info("job {}: its results are stored again", job->id());
    }
    if (job->restart_checkpoint_seq != 0 && cp.merge_seq >= job->restart_checkpoint_seq) {
      job->restart_checkpoint_seq = 0;
      if (!job->restart_pending() && job->active()) job->RestartClock(clock_.Now());
    }
    if (!job->held() && queue_.Unhold(*job)) {
      spdlog::info("job {}: resumed: its results can be stored{}", job->id(),
                   job->epoch() > 0 ? " and its restart is stored" : "");
      ServeWaiters(fx);
    }
    job->ReleaseAccumulator(path);  // a finished job's image now lives on disk only
  }
  Run(fx);
}

void Scheduler::CheckpointNotStored(const std::string& job_id, uint64_t merge_seq,
                                    const std::string& reason) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    Job* job = jobs_.Find(job_id);
    if (!job) return;
    if (job->checkpoint_collected_seq == merge_seq)
      job->checkpoint_collected_seq = job->checkpoint_written_seq;
    job->checkpoint_retry = true;
    job->results_storage_error = "checkpoint not stored: " + reason;
    fx.changed.insert(job->id());  // no persist wake: the persister retries on its own timer
  }
  Run(fx);
}

void Scheduler::ResultsJournaled(const std::string& job_id, std::span<const uint64_t> task_ids) {
  std::lock_guard lock(mu_);
  Job* job = jobs_.Find(job_id);
  if (!job) return;
  for (uint64_t id : task_ids)
    if (id < job->num_tasks()) job->MarkStored(id);
}

void Scheduler::ResultsNotStored(const std::string& job_id, const std::string& reason) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    Job* job = jobs_.Find(job_id);
    if (!job) return;
    job->results_storage_error = "results not stored: " + reason;
    job->checkpoint_retry = true;
    if (job->active() && !job->paused_for_storage) {
      job->paused_for_storage = true;
      queue_.Hold(*job);
      spdlog::error("job {}: paused: its results cannot be stored ({}); no new leases until they can",
                    job->id(), reason);
    }
    fx.changed.insert(job->id());
  }
  Run(fx);
}

void Scheduler::ForceCheckpoint(const std::string& job_id) {
  std::lock_guard lock(mu_);
  if (Job* job = jobs_.Find(job_id)) job->checkpoint_retry = true;
}

RowBatch Scheduler::CollectRows() {
  uint64_t released = 0;
  RowBatch batch = CollectRowsLocked(&released);
  // A released task list is mostly small blocks (the queue's tree nodes, its strings), which
  // malloc keeps for reuse: a cancelled 2^20-task job left ~100 MiB resident. Given back to the
  // system off the lock.
  if (released >= kReturnMemoryAfterTasks) ReturnFreedMemory();
  return batch;
}

RowBatch Scheduler::CollectRowsLocked(uint64_t* released) {
  RowBatch batch;
  std::lock_guard lock(mu_);
  for (Job* job : jobs_.InSubmissionOrder()) {
    // A finished job's final row waits for its final checkpoint to be stored, and for its final
    // noise estimate (docs/farm.md "Durability", D2). Its transition woke the persister.
    const bool held_back =
        !job->active() && (job->merge_seq() > job->checkpoint_written_seq ||
                           (job->accumulator_if_loaded() && job->noise_checked_seq != job->merge_seq()));
    if (job->row_dirty && !held_back) {
      JobRow row;
      row.job_id = job->id();
      row.seq = job->seq();
      row.spec = job->config().spec.SerializeAsString();
      row.state = job->state();
      row.failure_reason = job->failure_reason();
      row.submitted_unix_ms = job->submitted_unix_ms();
      row.elapsed_seconds = job->ElapsedSeconds(clock_.Now());
      row.samples_merged = job->samples_merged;
      row.noise_rms = job->accumulator_if_loaded() ? job->noise_cache : job->stored_noise_rms;
      row.checkpoint = job->checkpoint_seal;
      row.epoch = job->epoch();
      row.finished_unix_ms = job->finished_unix_ms;
      for (const std::string& w : job->convicted_workers)
        row.convicted += (row.convicted.empty() ? "" : "\n") + w;
      batch.jobs.push_back(std::move(row));
      job->row_dirty = false;
    }
    // A finished job whose task rows (from earlier flushes, one flush at a time) and final
    // checkpoint are stored needs its tasks no more (docs/farm.md "Coordinator memory").
    if (!job->active() && !job->tasks_released() && job->dirty_tasks.empty() &&
        job->merge_seq() == job->checkpoint_written_seq)
      *released += ReleaseFinishedTasks(*job);
    // A DONE row names a stored result (D2): a merged task whose result is not on disk yet waits.
    for (auto it = job->dirty_tasks.begin(); it != job->dirty_tasks.end();) {
      const TaskRuntime& rt = job->runtime(*it);
      if (rt.state == TaskState::kDone && !rt.stored) {
        ++it;
        continue;
      }
      batch.tasks.push_back({job->id(), *it, rt.state, rt.attempts, rt.failures, rt.last_error});
      it = job->dirty_tasks.erase(it);
    }
  }
  return batch;
}

uint64_t Scheduler::ReleaseFinishedTasks(Job& job) {
  for (uint64_t id = 0; id < job.num_tasks(); ++id)
    if (job.runtime(id).merging) return 0;  // a result being checked reads its task (Complete); next flush
  job.ReleaseTasks();
  load_.tasks -= std::exchange(job.charged_tasks, 0);
  load_.pixels -= std::exchange(job.charged_pixels, 0);
  sources_.erase(&job);
  for (auto it = held_.lower_bound({job.id(), 0}); it != held_.end() && it->first.first == job.id();)
    it = held_.erase(it);
  return job.num_tasks();
}

void Scheduler::RowsNotStored(const RowBatch& rows, const std::string& reason) {
  std::lock_guard lock(mu_);
  const std::string why = "rows not stored: " + reason;
  for (const JobRow& row : rows.jobs)
    if (Job* job = jobs_.Find(row.job_id)) {
      job->row_dirty = true;
      job->rows_storage_error = why;
    }
  for (const TaskRow& row : rows.tasks)
    if (Job* job = jobs_.Find(row.job_id)) {
      if (!job->tasks_released()) job->dirty_tasks.insert(row.task_id);
      job->rows_storage_error = why;
    }
}

void Scheduler::RowsStored(const RowBatch& rows) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    for (const JobRow& row : rows.jobs) {
      Job* job = jobs_.Find(row.job_id);
      if (!job) continue;
      job->rows_storage_error.clear();
      // A restart is stored once its row (epoch, convicted workers) is, and its empty checkpoint.
      if (job->restart_row_pending && row.epoch == job->epoch()) {
        job->restart_row_pending = false;
        if (!job->restart_pending() && job->active()) job->RestartClock(clock_.Now());
        if (!job->held() && queue_.Unhold(*job)) {
          spdlog::info("job {}: its restart is stored: leasing again", job->id());
          ServeWaiters(fx);
        }
      }
    }
    for (const TaskRow& row : rows.tasks)
      if (Job* job = jobs_.Find(row.job_id)) job->rows_storage_error.clear();
  }
  Run(fx);
}

bool Scheduler::HasUncheckpointedMerges() {
  std::lock_guard lock(mu_);
  for (Job* job : jobs_.InSubmissionOrder())
    if (job->accumulator_if_loaded() && job->merge_seq() > job->checkpoint_collected_seq) return true;
  return false;
}

void Scheduler::Shutdown() {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    shutdown_ = true;
    for (auto& [id, w] : waiters_) fx.callbacks.emplace_back(std::move(w.done), std::nullopt);
    waiters_.clear();
  }
  Run(fx);
}

}  // namespace pf::server
