#include "server/jobs/job.h"

#include <algorithm>
#include <stdexcept>

#include "common/plan/hierarchical.h"

namespace pf::server {

Job::Job(std::string id, uint64_t seq, std::shared_ptr<const JobConfig> config, std::vector<TaskSpec> tasks,
         int64_t submitted_unix_ms)
    : id_(std::move(id)),
      seq_(seq),
      config_(std::move(config)),
      tasks_(std::move(tasks)),
      runtime_(tasks_.size()),
      num_tasks_(tasks_.size()),
      submitted_unix_ms_(submitted_unix_ms) {
  counts_[size_t(TaskState::kQueued)] = tasks_.size();
  for (const TaskSpec& t : tasks_) CountIntoGroup(t);
  AddWork(tasks_);
}

void Job::AddWork(const std::vector<TaskSpec>& tasks) {
  const JobConfig& c = *config_;
  if (c.plan.kind == PlanKind::kMultipleMaps && c.plan.tail_tile_size != 0) {
    // Tail tiles (task_plan.h) are a quarter of a tile or less: progress and ETA count pixel
    // samples, as for the hierarchical plan, or the last 25 % of the pixels would read 57 % of
    // the job (the default farm job: 12 tiles + 16 tail tiles).
    for (const TaskSpec& t : tasks) {
      const uint64_t w =
          CountPixels(t.pixels, c.camera.width, c.image_height()) * (t.sample_end - t.sample_begin);
      task_work_.push_back(w);
      work_[size_t(TaskState::kQueued)] += w;
    }
    return;
  }
  if (c.plan.kind != PlanKind::kHierarchical) {
    work_[size_t(TaskState::kQueued)] += tasks.size();
    return;
  }
  const uint64_t photons = c.settings.integrator == IntegratorKind::kPhotonMap ? c.settings.photons : 0;
  for (uint64_t w : HierarchicalTaskWork(c.plan, c.camera.width, c.camera.height, photons, tasks)) {
    task_work_.push_back(w);
    work_[size_t(TaskState::kQueued)] += w;
  }
}

void Job::CountIntoGroup(const TaskSpec& t) {
  if (!config_->frames.empty()) {
    frame_done_.resize(config_->frames.size(), 0);
    frame_total_.resize(config_->frames.size(), 0);
    frame_cancelled_.resize(config_->frames.size(), 0);
    ++frame_total_.at(t.frame);
  }
  const uint64_t g = GroupOf(t);
  if (g >= group_remaining_.size()) {
    group_remaining_.resize(g + 1, 0);
    group_total_.resize(g + 1, 0);
  }
  if (group_total_[g] > 0 && group_remaining_[g] == 0) --full_coverage_;  // complete no more
  ++group_remaining_[g];
  ++group_total_[g];
}

void Job::AppendTasks(const std::vector<TaskSpec>& tasks) {
  for (const TaskSpec& t : tasks) {
    if (t.task_id != tasks_.size())
      throw std::logic_error("job " + id_ + ": appended task id " + std::to_string(t.task_id) +
                             ", expected " + std::to_string(tasks_.size()));
    tasks_.push_back(t);
    runtime_.emplace_back();
    ++num_tasks_;
    ++counts_[size_t(TaskState::kQueued)];
    dirty_tasks.insert(t.task_id);
    CountIntoGroup(t);
  }
  AddWork(tasks);
}

void Job::Restart(std::vector<TaskSpec> tasks, double now) {
  tasks_ = std::move(tasks);
  num_tasks_ = tasks_.size();
  runtime_.assign(tasks_.size(), TaskRuntime{});
  for (uint64_t& c : counts_) c = 0;
  counts_[size_t(TaskState::kQueued)] = tasks_.size();
  for (uint64_t& w : work_) w = 0;
  task_work_.clear();
  AddWork(tasks_);
  group_remaining_.clear();
  group_total_.clear();
  frame_done_.clear();
  frame_total_.clear();
  frame_cancelled_.clear();
  full_coverage_ = 0;
  for (const TaskSpec& t : tasks_) CountIntoGroup(t);
  // An empty accumulator, not none: the persister checkpoints loaded accumulators only, and the
  // checkpoint of nothing is what replaces the old image on disk.
  accumulator_ = std::make_unique<Accumulator>(config_->plan, config_->camera.width, config_->image_height(),
                                               config_->settings.progressive_alpha);
  ++merge_seq_;
  ++epoch_;
  samples_merged = 0;
  work_to_create = 0;
  progress_shown = 0;
  eta = EtaEstimator{};
  // The discarded work does not count against a time budget: the job's clock starts again (a
  // budget already spent would end the restarted job at once, with an empty image).
  stopping = false;
  elapsed_before_ = 0;
  if (running_since_) running_since_ = now;
  noise_cache = -1;
  estimates_cache = {};
  target_missed.clear();
  noise_checked_seq = ~uint64_t(0);
  noise_checked_at = -1e300;
  noise_target_checked_at = -1e300;
  noise_checked_coverage = 0;
  dirty_tasks.clear();
  for (uint64_t id = 0; id < tasks_.size(); ++id) dirty_tasks.insert(id);
  row_dirty = true;
  checkpoint_retry = true;
  restart_checkpoint_seq = merge_seq_;
  restart_row_pending = true;
}

Accumulator& Job::accumulator() {
  if (!accumulator_)
    accumulator_ = std::make_unique<Accumulator>(
        config_->plan, config_->camera.width, config_->image_height(), config_->settings.progressive_alpha);
  return *accumulator_;
}

void Job::ReleaseAccumulator(const std::string& path) {
  if (active() || !accumulator_ || checkpoint_written_seq != merge_seq_) return;
  stored_samples_merged = accumulator_->samples_merged();
  stored_noise_rms = noise_cache;
  stored_estimates = estimates_cache;
  checkpoint_path = path;
  accumulator_.reset();
}

uint64_t Job::GroupOf(const TaskSpec& t) const {
  return config_->plan.kind == PlanKind::kSkipping ? t.round : t.map_index;
}

bool Job::CanTransition(JobState from, JobState to) {
  if (IsTerminal(from)) return false;
  switch (to) {
    case JobState::kQueued:
      return false;
    case JobState::kRunning:
      return from == JobState::kQueued;
    case JobState::kSucceeded:
      return from == JobState::kRunning;
    case JobState::kFailed:
    case JobState::kCancelled:
      return true;
  }
  return false;
}

void Job::TransitionTo(JobState next, double now, const std::string& reason) {
  if (!CanTransition(state_, next))
    throw std::logic_error("job " + id_ + ": illegal transition " + JobStateName(state_) + " -> " +
                           JobStateName(next));
  if (next == JobState::kRunning) running_since_ = now;
  if (IsTerminal(next) && running_since_) {
    elapsed_before_ += now - *running_since_;
    running_since_.reset();
  }
  state_ = next;
  if (next == JobState::kFailed) failure_reason_ = reason;
  row_dirty = true;
}

void Job::RestoreState(JobState state, const std::string& reason, double now) {
  state_ = state;
  failure_reason_ = reason;
  running_since_.reset();
  if (state == JobState::kRunning) running_since_ = now;
}

void Job::SetTaskState(uint64_t id, TaskState next) {
  TaskRuntime& rt = runtime_.at(id);
  if (!frame_done_.empty()) {
    const uint32_t frame = tasks_.at(id).frame;
    if ((rt.state == TaskState::kDone) != (next == TaskState::kDone))
      next == TaskState::kDone ? ++frame_done_.at(frame) : --frame_done_.at(frame);
    if ((rt.state == TaskState::kCancelled) != (next == TaskState::kCancelled))
      next == TaskState::kCancelled ? ++frame_cancelled_.at(frame) : --frame_cancelled_.at(frame);
  }
  --counts_[size_t(rt.state)];
  ++counts_[size_t(next)];
  work_[size_t(rt.state)] -= task_work(id);
  work_[size_t(next)] += task_work(id);
  rt.state = next;
  if (next != TaskState::kDone) rt.stored = false;
  if (next != TaskState::kLeased) {
    rt.lease_id.clear();
    rt.lease_deadline = 0;
    rt.progress = 0;
  }
  dirty_tasks.insert(id);
}

void Job::CancelAsJobEnds(uint64_t id) {
  SetTaskState(id, TaskState::kCancelled);
  dirty_tasks.erase(id);
}

void Job::ReleaseTasks() {
  if (active() || tasks_released_) return;
  // swap, not clear(): clear keeps the capacity.
  std::vector<TaskSpec>().swap(tasks_);
  std::vector<TaskRuntime>().swap(runtime_);
  std::vector<uint64_t>().swap(task_work_);
  std::vector<uint64_t>().swap(group_remaining_);
  std::vector<uint64_t>().swap(group_total_);
  dirty_tasks.clear();
  tasks_released_ = true;
}

std::unique_ptr<Job> Job::Finished(std::string id, uint64_t seq, std::shared_ptr<const JobConfig> config,
                                   uint64_t tasks, uint64_t done, int64_t submitted_unix_ms) {
  auto job = std::make_unique<Job>(std::move(id), seq, std::move(config), std::vector<TaskSpec>{},
                                   submitted_unix_ms);
  done = std::min(done, tasks);
  job->num_tasks_ = tasks;
  job->counts_[size_t(TaskState::kDone)] = job->work_[size_t(TaskState::kDone)] = done;
  job->counts_[size_t(TaskState::kCancelled)] = job->work_[size_t(TaskState::kCancelled)] = tasks - done;
  job->counts_[size_t(TaskState::kQueued)] = job->work_[size_t(TaskState::kQueued)] = 0;
  job->tasks_released_ = true;
  return job;
}

void Job::RecordMerge(uint64_t task_id) {
  SetTaskState(task_id, TaskState::kDone);
  ++merge_seq_;
  uint64_t& remaining = group_remaining_.at(GroupOf(tasks_.at(task_id)));
  if (--remaining == 0) ++full_coverage_;
}

void Job::MarkStored(uint64_t task_id) {
  if (task_id >= runtime_.size()) return;  // released: its checkpoint stored every result
  TaskRuntime& rt = runtime_.at(task_id);
  if (rt.state != TaskState::kDone || rt.stored) return;
  rt.stored = true;
  dirty_tasks.insert(task_id);
}

std::vector<uint64_t> Job::MergedTaskIds() const {
  std::vector<uint64_t> ids;
  ids.reserve(counts_[size_t(TaskState::kDone)]);
  for (size_t i = 0; i < runtime_.size(); ++i)
    if (runtime_[i].state == TaskState::kDone) ids.push_back(i);
  return ids;
}

uint32_t Job::rounds_done() const {
  if (config_->plan.kind == PlanKind::kSkipping) return full_coverage_;
  return count(TaskState::kDone) == num_tasks_ && num_tasks_ > 0 ? 1 : 0;
}

double Job::ElapsedSeconds(double now) const {
  return elapsed_before_ + (running_since_ ? now - *running_since_ : 0.0);
}

}  // namespace pf::server
