#include "worker/scene_obtainer.h"

#include <spdlog/spdlog.h>

#include "common/core/error.h"

namespace pf::worker {

SceneObtainer::SceneObtainer(CoordinatorClient& client, std::filesystem::path cache_dir,
                             size_t memory_capacity)
    : client_(client), scenes_(std::move(cache_dir), memory_capacity) {}

std::optional<TaskEnd> SceneObtainer::Obtain(const photonfarm::v1::Task& task, const std::string& ctx,
                                             std::shared_ptr<const SceneRuntime>* scene) {
  try {
    std::string source;
    *scene = scenes_.Get(
        task.scene_hash(), [&] { return client_.FetchScene(task.scene_hash(), task.scene_entry()); },
        &source);
    if (source != "memory")
      spdlog::info("scene {} from {} for {}", task.scene_hash().substr(0, 12), source, ctx);
  } catch (const RpcError& e) {
    if (IsConnectionError(e.status())) {
      spdlog::warn("FetchScene for {}: {}; the lease will expire", ctx, StatusToString(e.status()));
      return TaskEnd::Unreachable();
    }
    return TaskEnd::Failed("fetching scene " + task.scene_hash() + ": " + StatusToString(e.status()),
                           e.status().error_code() != grpc::StatusCode::NOT_FOUND);
  } catch (const InputError& e) {
    return TaskEnd::Failed(std::string("scene ") + task.scene_hash() + ": " + e.what(), false);
  } catch (const std::exception& e) {
    return TaskEnd::Failed(std::string("scene ") + task.scene_hash() + ": " + e.what(), true);
  }
  return std::nullopt;
}

}  // namespace pf::worker
