#include "server/scheduling/referee.h"

#include "common/plan/frame_tasks.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "common/core/error.h"
#include "common/plan/task_executor.h"
#include "common/scene/scene_bundle.h"
#include "server/assembly/result_merger.h"
#include "server/jobs/job_spec.h"
#include "server/scheduling/scheduler.h"
#include "server/store/scene_store.h"

namespace pf::server {

Referee::Referee(SceneStore& scenes, int threads) : scenes_(scenes), threads_(threads < 1 ? 1 : threads) {}

Referee::~Referee() {
  Stop();
}

void Referee::Stop() {
  stopping_ = true;
  executor_.Stop();  // runs what is queued: each sees stopping_ and returns at once
}

Referee::Counters Referee::counters() const {
  std::lock_guard lock(mu_);
  return counters_;
}

void Referee::Judge(RefereeCase c) {
  if (stopping_) return;
  auto shared = std::make_shared<RefereeCase>(std::move(c));
  executor_.Post([this, shared] { Render(*shared); });
}

std::shared_ptr<const SceneRuntime> Referee::SceneOf(const std::string& hash, const std::string& entry) {
  std::lock_guard lock(mu_);
  if (scene_ && scene_hash_ == hash) return scene_;
  scene_.reset();
  scene_ = std::make_shared<const SceneRuntime>(LoadBundle(scenes_.DirectoryOf(hash), entry));
  scene_hash_ = hash;
  return scene_;
}

void Referee::Render(const RefereeCase& c) {
  if (stopping_ || !scheduler_) return;
  const JobConfig& config = *c.config;
  const auto t0 = std::chrono::steady_clock::now();
  std::string digest, error;
  try {
    const std::shared_ptr<const SceneRuntime> scene = SceneOf(config.scene_hash, config.scene_entry);
    // As a worker renders it (worker_service.cpp): an animation's task with its frame's camera.
    const TaskOutput out =
        ExecuteTask(*scene, config.scene_hash, config.CameraOf(c.task), config.settings,
                    FrameLocalTask(c.task, config.camera.height), threads_, &maps_, nullptr, &stopping_);
    digest = ResultMerger::Digest(out.rgb_sums);
  } catch (const Cancelled&) {
    return;  // stopping: no verdict
  } catch (const std::exception& e) {
    error = e.what();
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  {
    std::lock_guard lock(mu_);
    ++(error.empty() ? counters_.rendered : counters_.failed);
    counters_.seconds += seconds;
  }
  if (error.empty())
    spdlog::info("referee: job {} task {} rendered by the coordinator in {:.3f} s", c.job_id, c.task.task_id,
                 seconds);
  else
    spdlog::error("referee: job {} task {}: the coordinator could not render it: {}", c.job_id,
                  c.task.task_id, error);
  if (stopping_) return;
  scheduler_->RefereeVerdict(c.verification_id, digest, error);
}

}  // namespace pf::server
