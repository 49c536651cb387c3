#pragma once
// A leased task's scene (docs/design.md, S2: workers receive the bundle and build their own runtime
// scene): from memory, from the disk cache (scene_cache.h) or by FetchScene, whose files must hash
// to the task's scene_hash (coordinator_client.h). What a failure means for the task — failed
// permanently, failed for retry, or left to expire while the coordinator is away — is decided here.

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "photonfarm/v1/farm.pb.h"
#include "worker/coordinator_client.h"
#include "worker/leased_task.h"
#include "worker/scene_cache.h"

namespace pf::worker {

class SceneObtainer {
 public:
  // `client` outlives the obtainer; `cache_dir`, `memory_capacity`: SceneCache's.
  SceneObtainer(CoordinatorClient& client, std::filesystem::path cache_dir, size_t memory_capacity);

  // Sets *scene (logged unless it was in memory); else returns how the task ends.
  std::optional<TaskEnd> Obtain(const photonfarm::v1::Task& task, const std::string& ctx,
                                std::shared_ptr<const SceneRuntime>* scene);

 private:
  CoordinatorClient& client_;
  SceneCache scenes_;
};

}  // namespace pf::worker
