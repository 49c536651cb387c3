#pragma once
// One leased task's execution, shared by the pull loop, the render thread (StartRender) and the
// heartbeat thread (lease_keeper.h): whether the render is done and with what, its progress,
// whether the lease is gone and whether the render should stop early.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "common/photon/map_cache.h"
#include "common/plan/task_executor.h"
#include "common/render/scene_runtime.h"
#include "worker/leased_task.h"

namespace pf::worker {

struct TaskExecution {
  // `lease_seconds` <= 0 means 30 s; `pixels` (of the subset) is at least 1 for the progress.
  TaskExecution(uint64_t pixels, double lease_seconds);

  std::mutex mutex;
  std::condition_variable cv;
  bool done = false;  // the render thread finished (output or error set)
  bool stop_heartbeat = false;
  bool lease_lost = false;
  std::optional<TaskOutput> output;
  std::string error;
  bool error_retryable = true;
  std::atomic<uint64_t> progress{0};
  // Set when the result can no longer count (the lease is gone, or it was handed back): the
  // render stops within a block of pixels or a chunk of photons instead of running to the end.
  std::atomic<bool> cancel{false};
  bool cancelled = false;  // the render thread stopped because of `cancel`
  const uint64_t pixels;
  const double lease_seconds;
};

// Renders the task on a thread of its own (ExecuteTask with `threads`), which owns what it uses:
// it is detached on a hand-back and may outlive the loop. Sets exec->done at its end.
std::thread StartRender(std::shared_ptr<TaskExecution> exec, std::shared_ptr<const SceneRuntime> scene,
                        const ParsedTask& parsed, const std::string& scene_hash,
                        std::shared_ptr<PhotonMapCache> maps, int threads);

}  // namespace pf::worker
