#include "worker/task_execution.h"

#include <algorithm>

#include "common/core/error.h"

namespace pf::worker {

TaskExecution::TaskExecution(uint64_t pixels, double lease_seconds)
    : pixels(std::max<uint64_t>(pixels, 1)), lease_seconds(lease_seconds > 0 ? lease_seconds : 30.0) {}

std::thread StartRender(std::shared_ptr<TaskExecution> exec, std::shared_ptr<const SceneRuntime> scene,
                        const ParsedTask& parsed, const std::string& scene_hash,
                        std::shared_ptr<PhotonMapCache> maps, int threads) {
  return std::thread([exec, scene, camera = parsed.camera, settings = parsed.settings, spec = parsed.spec,
                      hash = scene_hash, maps, threads] {
    std::optional<TaskOutput> out;
    std::string error;
    bool retryable = true, cancelled = false;
    try {
      out = ExecuteTask(*scene, hash, camera, settings, spec, threads, maps.get(), &exec->progress,
                        &exec->cancel);
    } catch (const Cancelled&) {
      error = "cancelled";
      cancelled = true;
    } catch (const InputError& e) {
      error = e.what();
      retryable = false;
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard lock(exec->mutex);
    exec->output = std::move(out);
    exec->error = error;
    exec->error_retryable = retryable;
    exec->cancelled = cancelled;
    exec->done = true;
    exec->cv.notify_all();
  });
}

}  // namespace pf::worker
