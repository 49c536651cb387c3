#pragma once
// A job inside the coordinator: its validated configuration, its tasks with their runtime state,
// its accumulator, and the job state machine
//
//     QUEUED ──▶ RUNNING ──▶ SUCCEEDED | FAILED | CANCELLED
//        └───────────────────▶ FAILED | CANCELLED
//
// (TransitionTo enforces it; terminal states are final). A task is QUEUED → LEASED → DONE, or
// LEASED → QUEUED again (lease expired, failed, result rejected, lease returned), or CANCELLED
// (job cancelled, stopped by a stop rule, or failed).
//
// Not thread-safe by itself: the Scheduler owns every Job and serialises access with its lock,
// except for the accumulator, which is guarded by the job's own image_mu so that the O(pixels)
// work (merging a result, resolving a snapshot, serialising a checkpoint, the noise estimate)
// runs off the Scheduler's lock (server/scheduling/scheduler.h, "Locks").

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/plan/accumulator.h"
#include "common/plan/task_plan.h"
#include "server/jobs/eta_estimator.h"
#include "server/jobs/job_spec.h"
#include "server/store/records.h"

namespace pf::server {

struct TaskRuntime {
  TaskState state = TaskState::kQueued;
  uint32_t attempts = 0;  // leases handed out (the current/next lease's attempt number)
  uint32_t failures = 0;  // attempts that ended badly (all of them; stored)
  // The distinct workers whose attempts of this task failed, and failed attempts with no worker to
  // attribute them to: the task fails its job once these reach max_attempts, so one bad worker
  // cannot use up a task's attempts (server/scheduling/worker_health.h). In memory only: a
  // restarted coordinator counts afresh.
  std::vector<std::string> failed_workers;
  uint32_t unattributed_failures = 0;
  std::string lease_id;  // current lease while kLeased
  std::string worker_id;
  double lease_deadline = 0;  // Clock::Now() seconds
  double progress = 0;        // 0..1 as reported by ExtendLease
  std::string last_error;
  // The last result above the job's plausibility bound (ResultMerger::Digest) and the worker that
  // sent it: a bit-identical result from another worker is merged (Scheduler::Complete).
  std::string implausible_digest;
  std::string implausible_worker;
  // A result of the current lease is being checked and merged (Scheduler::Complete, between its
  // claim and its commit): the lease does not expire, cannot be failed and a second result for
  // it is ignored. The result arrived while the lease was live, so it decides the attempt.
  bool merging = false;
  // DONE and its result is on disk (in the job's journal or a verified checkpoint). Only then is
  // its row written as DONE, so a DONE row always names a stored result and recovery can tell
  // acknowledged results that were lost (docs/farm.md, "Durability").
  bool stored = false;
};

class Job {
 public:
  // No accumulator yet: it is allocated when the first result is merged (accumulator()), so a
  // queued job costs O(tasks), not O(pixels) (a 4096² job's accumulator is ~787 MB), and freed
  // once a finished job's final checkpoint is on disk (ReleaseAccumulator); from then on, as for
  // finished jobs reloaded from the store, the image is read from the checkpoint file on demand.
  Job(std::string id, uint64_t seq, std::shared_ptr<const JobConfig> config, std::vector<TaskSpec> tasks,
      int64_t submitted_unix_ms);

  const std::string& id() const { return id_; }
  uint64_t seq() const { return seq_; }
  const JobConfig& config() const { return *config_; }
  std::shared_ptr<const JobConfig> shared_config() const { return config_; }
  // A finished job as recovery restores it: its counts, not its tasks — `done` of `tasks` DONE,
  // the others CANCELLED (a finished job has nothing queued or leased) — as after ReleaseTasks.
  // Progress counts 1 per task (task_work needs the task list).
  static std::unique_ptr<Job> Finished(std::string id, uint64_t seq, std::shared_ptr<const JobConfig> config,
                                       uint64_t tasks, uint64_t done, int64_t submitted_unix_ms);

  const std::vector<TaskSpec>& tasks() const { return tasks_; }
  const TaskSpec& task(uint64_t id) const { return tasks_.at(id); }
  TaskRuntime& runtime(uint64_t id) { return runtime_.at(id); }
  // Whether task `id` has a runtime: not after its tasks were released, nor an appended task after
  // a restart went back to the plan's scheduled tasks.
  bool has_runtime(uint64_t id) const { return id < runtime_.size(); }
  const TaskRuntime& runtime(uint64_t id) const { return runtime_.at(id); }
  size_t num_tasks() const { return num_tasks_; }
  // A finished job keeps what its status needs (counts, work, coverage), not its task list
  // (docs/farm.md "Coordinator memory": ~440 bytes per task, 2^20 tasks per job). Call once no
  // lease, row or checkpoint needs a task any more (Scheduler::CollectRows); afterwards tasks()
  // is empty and task(id)/runtime(id) throw std::out_of_range.
  void ReleaseTasks();
  bool tasks_released() const { return tasks_released_; }
  // Tasks a dynamic plan created from merged results (server/scheduling/task_source.h), QUEUED;
  // their ids must continue the numbering (task_id = num_tasks(), +1, …): std::logic_error if not.
  void AppendTasks(const std::vector<TaskSpec>& tasks);
  // Starts the job's work again from nothing (results of a convicted worker are in its image:
  // docs/farm.md "Result verification"): `tasks` (the plan's static tasks) all QUEUED with fresh
  // attempts, an empty accumulator, coverage and ETA reset. merge_seq goes *up* by one, so the
  // next checkpoint (of nothing) supersedes every earlier one, and `epoch` counts the restarts:
  // a result merged before a restart is not journaled after it (the persister asks) and not
  // replayed from the journal (entries carry their epoch). The state
  // (RUNNING) stays; the elapsed time starts again at `now` (a time budget is the new run's).
  // Call with image_mu and the Scheduler's lock held.
  void Restart(std::vector<TaskSpec> tasks, double now);
  uint32_t epoch() const { return epoch_; }
  void RestoreEpoch(uint32_t epoch) { epoch_ = epoch; }  // recovery (JobRow.epoch)
  // Workers convicted of a wrong result of this job, in conviction order (stored in its row, so
  // that a restarted coordinator keeps them off the job).
  std::vector<std::string> convicted_workers;

  JobState state() const { return state_; }
  const std::string& failure_reason() const { return failure_reason_; }
  bool active() const { return !IsTerminal(state_); }
  // Throws std::logic_error for a transition the state machine does not allow.
  void TransitionTo(JobState next, double now, const std::string& reason = "");
  static bool CanTransition(JobState from, JobState to);
  // Recovery: the state as stored (no transition check); a RUNNING job's clock restarts at `now`.
  void RestoreState(JobState state, const std::string& reason, double now);

  // Task state changes keep the counters right; every call marks the task dirty (persist).
  void SetTaskState(uint64_t id, TaskState next);
  // A queued or leased task cancelled because its job ends: like SetTaskState, but its row is
  // not written — the job's terminal row says it (recovery counts a finished job's tasks that are
  // not DONE as CANCELLED), so cancelling a 2^20-task job writes one row, not 2^20.
  void CancelAsJobEnds(uint64_t id);
  uint64_t count(TaskState s) const { return counts_[size_t(s)]; }
  // Work, for progress and the ETA: 1 per task, except for the hierarchical plan, whose tasks
  // differ in cost by orders of magnitude: pixel samples plus its map (HierarchicalTaskWork).
  uint64_t task_work(uint64_t id) const { return task_work_.empty() ? 1 : task_work_.at(id); }
  uint64_t work(TaskState s) const { return work_[size_t(s)]; }
  // An animation's tasks per frame (index: the frame's among the job's): merged, scheduled, and
  // cancelled (by a stop rule, a cancel or a failure). Kept when the tasks are released (O(frames));
  // empty for a still image and for a finished job reloaded after a restart (it has no tasks).
  const std::vector<uint64_t>& frame_done() const { return frame_done_; }
  const std::vector<uint64_t>& frame_total() const { return frame_total_; }
  const std::vector<uint64_t>& frame_cancelled() const { return frame_cancelled_; }

  // Guards the accumulator (its content and whether it is loaded). Lock order: image_mu before the
  // Scheduler's lock, never the other way round.
  std::mutex image_mu;
  // Merge bookkeeping (the accumulator itself is changed by assembly/). accumulator() allocates
  // an empty one if there is none (call it only to merge into it).
  Accumulator& accumulator();
  const Accumulator* accumulator_if_loaded() const { return accumulator_.get(); }
  void set_accumulator(std::unique_ptr<Accumulator> acc) { accumulator_ = std::move(acc); }
  // A finished job whose final checkpoint (all its merges) is written to `path`: drops the
  // accumulator, keeping what the status needs. No-op for active jobs or stale checkpoints.
  void ReleaseAccumulator(const std::string& path);
  void RecordMerge(uint64_t task_id);  // marks done, bumps merge_seq and coverage counters
  // The merged task's result is on disk: its DONE row may be written.
  void MarkStored(uint64_t task_id);
  uint64_t merge_seq() const { return merge_seq_; }
  std::vector<uint64_t> MergedTaskIds() const;
  // Rounds (skipping) or maps (other plans) whose every task is merged: every pixel has that
  // many independent maps (the noise-target rule needs 2).
  uint32_t full_coverage() const { return full_coverage_; }
  uint32_t rounds_done() const;

  // Timing: elapsed counts while RUNNING, across coordinator restarts.
  double ElapsedSeconds(double now) const;
  void RestoreElapsed(double seconds) { elapsed_before_ = seconds; }
  // The restart is stored and the job leases again: its time budget counts from now (the hold
  // was no rendering time).
  void RestartClock(double now) {
    elapsed_before_ = 0;
    if (running_since_) running_since_ = now;
  }
  // Restarted and not yet stored (restart_checkpoint_seq, restart_row_pending).
  bool restart_pending() const { return restart_checkpoint_seq != 0 || restart_row_pending; }
  // Held back from leasing (TaskQueue::Hold) for any reason: a user's pause, its results cannot
  // be stored, or its restart is not stored yet.
  bool held() const { return paused || paused_for_storage || restart_pending() || !waiting_for.empty(); }
  // The jobs of its spec.after that have not succeeded yet (docs/farm.md "Job dependencies"):
  // held until none is left. In memory: AddJob derives it from the other jobs' states.
  std::set<std::string> waiting_for;
  // Its deletion has begun (Scheduler::CheckRemovable): no new job may name it in --after. Stays
  // set if the deletion then fails (a later one proceeds).
  bool deleting = false;
  // Its dependencies succeeded once already: a SUCCEEDED job that recovery renders again (its
  // image failed its seal) does not wait for them, nor fails if one was deleted since.
  bool dependencies_met = false;
  int64_t submitted_unix_ms() const { return submitted_unix_ms_; }
  // When it reached its terminal state (Unix ms; Scheduler::FinishJob, stored in its row); 0 while
  // active. pf purge --older-than reads it (docs/farm.md "Deleting jobs").
  int64_t finished_unix_ms = 0;

  // ETA from recent throughput (Scheduler: RecordCompletion on every merge of a live result).
  EtaEstimator eta;
  // The largest progress shown so far (JobStatus.progress never goes backwards when an estimate
  // of work still to be created is revised up; the ETA uses the current estimate).
  double progress_shown = 0;

  // Stop rules.
  bool stopping = false;                    // time budget reached: nothing new is scheduled
  double noise_checked_at = -1e300;         // status cache of EstimatedNoiseRms
  double noise_target_checked_at = -1e300;  // last evaluation of the target-noise rule
  uint64_t noise_checked_seq = ~uint64_t(0);
  uint32_t noise_checked_coverage = 0;
  double noise_cache = -1;
  ErrorEstimates estimates_cache;  // all of them (noise_cache = its noise)
  // Set when the job succeeds without meeting its target (stop_rules.h): DescribeTargets' line.
  // In memory: a restarted coordinator does not know it.
  std::string target_missed;
  // Sets the cached estimates (computed by the caller from this job's accumulator).
  void SetNoise(const ErrorEstimates& e, double now) {
    noise_cache = e.noise;
    estimates_cache = e;
    noise_checked_at = now;
    noise_checked_seq = merge_seq_;
    noise_checked_coverage = full_coverage_;
  }

  // Budgets (server/rpc/budgets.h): the client that submitted the job ("" for a job recovered after
  // a restart: the client is not stored, such jobs count against the global budgets only), and
  // the tasks and pixels the scheduler counts for it until its tasks are released (Scheduler::Load).
  std::string client;
  uint64_t charged_tasks = 0;
  uint64_t charged_pixels = 0;

  // Persistence bookkeeping (owned by the scheduler).
  bool row_dirty = false;
  // When the elapsed running time was last marked for persisting (Scheduler::Tick), so that a
  // time budget counts across coordinator restarts (docs/security.md).
  double elapsed_marked_at = 0;
  std::set<uint64_t> dirty_tasks;
  uint64_t checkpoint_collected_seq = 0;  // merge_seq of the last checkpoint handed to the persister
  uint64_t checkpoint_written_seq = 0;    // merge_seq of the last checkpoint on disk and verified
  // The seal of that checkpoint (server/store/checkpoint.h): stored with the job's row, checked
  // whenever the image is read back from the file.
  CheckpointSeal checkpoint_seal;
  std::string checkpoint_path;  // for jobs whose accumulator is not loaded (finished, reloaded)
  // Storage (docs/farm.md, "Durability"): why the last write of the job's results (journal,
  // checkpoint) or of its rows failed, "" once a later one succeeded. Shown in the job's status.
  std::string results_storage_error;
  std::string rows_storage_error;
  // A result of the job could be stored neither in the journal nor in a checkpoint: no new
  // leases until a checkpoint of the job is written (the queue holds the job's tasks back).
  bool paused_for_storage = false;
  // Paused by a user (PauseJob, docs/farm.md "Pausing a job"): held like the above until ResumeJob.
  bool paused = false;
  // The last checkpoint failed: try again at every flush instead of waiting until one is due.
  bool checkpoint_retry = false;
  // Restarted (Restart) and held back from leasing until a checkpoint of merge_seq ≥ this is
  // stored and a row with its epoch: until then a crash would bring back what the restart threw
  // away (or forget who was convicted). 0 / false: not held for it.
  uint64_t restart_checkpoint_seq = 0;
  bool restart_row_pending = false;
  uint64_t stored_samples_merged = 0;  // their figures as last stored
  double stored_noise_rms = -1;
  // The estimates when the accumulator was released; in memory only (a restart keeps the noise).
  ErrorEstimates stored_estimates;
  // The accumulator's samples_merged as of its last merge, readable under the Scheduler's lock
  // alone (the accumulator needs image_mu); equals stored_samples_merged once it is released.
  uint64_t samples_merged = 0;
  // The task source's WorkToCreate as of the last merge (hierarchical: it reads the accumulator).
  uint64_t work_to_create = 0;

 private:
  std::string id_;
  uint64_t seq_;
  std::shared_ptr<const JobConfig> config_;
  std::vector<TaskSpec> tasks_;
  std::vector<TaskRuntime> runtime_;
  uint64_t num_tasks_ = 0;  // tasks_.size() until ReleaseTasks
  bool tasks_released_ = false;
  std::unique_ptr<Accumulator> accumulator_;
  JobState state_ = JobState::kQueued;
  std::string failure_reason_;
  uint64_t counts_[5] = {0, 0, 0, 0, 0};
  std::vector<uint64_t> task_work_;  // empty: 1 per task
  uint64_t work_[5] = {0, 0, 0, 0, 0};
  void AddWork(const std::vector<TaskSpec>& tasks);
  uint64_t merge_seq_ = 0;
  uint32_t epoch_ = 0;
  // Coverage: per group (round for skipping, map index otherwise) tasks still unmerged.
  std::vector<uint64_t> group_remaining_;
  std::vector<uint64_t> group_total_;
  std::vector<uint64_t> frame_done_, frame_total_, frame_cancelled_;
  void CountIntoGroup(const TaskSpec& t);
  uint32_t full_coverage_ = 0;
  uint64_t GroupOf(const TaskSpec& t) const;
  double elapsed_before_ = 0;
  std::optional<double> running_since_;
  int64_t submitted_unix_ms_;
};

}  // namespace pf::server
