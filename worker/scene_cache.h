#pragma once
// The worker's scene caches (docs/design.md, §1: bundles are content-addressed):
//  - on disk, under <cache-dir>/scenes/<hash>/ (the bundle's files, written with WriteBundle)
//    plus <cache-dir>/scenes/<hash>.entry (the entry path). A bundle is fetched at most once
//    per cache directory, survives worker restarts, and is re-hashed when read back (a corrupt
//    or tampered copy is fetched again).
//  - in memory, the last `memory_capacity` SceneRuntimes (description + Embree + lights), so
//    consecutive tasks of a job reuse the built acceleration structure.
// Thread-safe; Get() of a hash not yet in memory holds the cache lock while it loads (a worker
// runs one task at a time, so there is nothing to gain from finer locking).

#include <cstddef>
#include <filesystem>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/plan/task_executor.h"
#include "common/scene/scene_bundle.h"

namespace pf::worker {

class SceneCache {
 public:
  // Called when the bundle is in neither cache (e.g. FetchScene). May throw; the exception
  // propagates out of Get().
  using Fetcher = std::function<SceneBundle()>;

  SceneCache(std::filesystem::path cache_dir, size_t memory_capacity);

  // The runtime of the bundle with this hash. `source` (optional) receives "memory", "disk"
  // or "fetched". Throws InputError if the hash is malformed, the fetched bundle's hash differs
  // or the scene does not load (file:line), SystemError if the disk fails.
  std::shared_ptr<const SceneRuntime> Get(const std::string& hash, const Fetcher& fetch,
                                          std::string* source = nullptr);

  // Hashes of the bundles on disk (what a restarted worker finds again).
  std::vector<std::string> CachedHashes() const;

  // A hash is 64 lowercase hex digits (it becomes a directory name: nothing else is accepted).
  static bool IsValidHash(const std::string& hash);

 private:
  std::shared_ptr<const SceneRuntime> LoadFromDisk(const std::string& hash);
  void StoreOnDisk(const std::string& hash, const SceneBundle& bundle);

  std::filesystem::path dir_;
  size_t capacity_;
  mutable std::mutex mutex_;
  std::list<std::pair<std::string, std::shared_ptr<const SceneRuntime>>> memory_;  // most recent first
  std::vector<std::string> disk_hashes_;
};

}  // namespace pf::worker
