#include "worker/scene_cache.h"

#include <spdlog/spdlog.h>

#include <fstream>

#include "common/core/atomic_file.h"
#include "common/core/error.h"

namespace pf::worker {
namespace fs = std::filesystem;

SceneCache::SceneCache(fs::path cache_dir, size_t memory_capacity)
    : dir_(std::move(cache_dir) / "scenes"), capacity_(std::max<size_t>(memory_capacity, 1)) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw SystemError("--cache-dir: cannot create " + dir_.string() + ": " + ec.message());
  for (const fs::directory_entry& e : fs::directory_iterator(dir_)) {
    const std::string name = e.path().filename().string();
    if (e.is_directory() && IsValidHash(name) && fs::exists(dir_ / (name + ".entry")))
      disk_hashes_.push_back(name);
    // Left-overs of an interrupted store.
    if (IsTemporaryName(name)) fs::remove_all(e.path(), ec);
  }
}

bool SceneCache::IsValidHash(const std::string& hash) {
  if (hash.size() != 64) return false;
  for (char c : hash)
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  return true;
}

std::vector<std::string> SceneCache::CachedHashes() const {
  std::lock_guard lock(mutex_);
  return disk_hashes_;
}

std::shared_ptr<const SceneRuntime> SceneCache::LoadFromDisk(const std::string& hash) {
  const fs::path entry_file = dir_ / (hash + ".entry");
  const fs::path bundle_dir = dir_ / hash;
  std::ifstream in(entry_file);
  std::string entry;
  if (!in || !std::getline(in, entry) || !fs::is_directory(bundle_dir)) return nullptr;
  // Re-hash what is on disk: a copy that was corrupted or edited is fetched again.
  SceneBundle on_disk = CollectBundle(bundle_dir / entry);
  on_disk.entry = entry;
  if (BundleHash(on_disk) != hash) {
    spdlog::warn("scene cache: {} on disk does not match its hash; fetching it again", bundle_dir.string());
    std::error_code ec;
    fs::remove(entry_file, ec);
    fs::remove_all(bundle_dir, ec);
    std::erase(disk_hashes_, hash);
    return nullptr;
  }
  return std::make_shared<const SceneRuntime>(LoadBundle(bundle_dir, entry));
}

void SceneCache::StoreOnDisk(const std::string& hash, const SceneBundle& bundle) {
  // Write to a private temporary folder, then rename: a crash never leaves a half-written
  // bundle under its hash, and workers sharing the cache directory do not collide.
  const fs::path tmp = TemporarySibling(dir_ / hash);
  WriteBundle(bundle, tmp);
  PublishDirectory(tmp, dir_ / hash);  // false: another worker stored it first (same content)
  WriteFileAtomically(dir_ / (hash + ".entry"), bundle.entry + "\n");
  if (std::find(disk_hashes_.begin(), disk_hashes_.end(), hash) == disk_hashes_.end())
    disk_hashes_.push_back(hash);
}

std::shared_ptr<const SceneRuntime> SceneCache::Get(const std::string& hash, const Fetcher& fetch,
                                                    std::string* source) {
  if (!IsValidHash(hash)) throw InputError("task.scene_hash: '" + hash + "' is not 64 lowercase hex digits");
  std::lock_guard lock(mutex_);
  for (auto it = memory_.begin(); it != memory_.end(); ++it)
    if (it->first == hash) {
      memory_.splice(memory_.begin(), memory_, it);
      if (source) *source = "memory";
      return memory_.front().second;
    }
  std::shared_ptr<const SceneRuntime> runtime = LoadFromDisk(hash);
  if (runtime) {
    if (source) *source = "disk";
  } else {
    SceneBundle bundle = fetch();
    const std::string got = BundleHash(bundle);
    if (got != hash) throw InputError("fetched scene bundle hashes to " + got + ", expected " + hash);
    StoreOnDisk(hash, bundle);
    runtime = std::make_shared<const SceneRuntime>(LoadBundle(dir_ / hash, bundle.entry));
    if (source) *source = "fetched";
  }
  memory_.emplace_front(hash, runtime);
  while (memory_.size() > capacity_) memory_.pop_back();
  return runtime;
}

}  // namespace pf::worker
