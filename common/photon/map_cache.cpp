#include "common/photon/map_cache.h"

#include <utility>

namespace pf {

std::shared_ptr<const PhotonMaps> PhotonMapCache::Find(const std::string& key) {
  std::lock_guard lock(mutex_);
  for (auto it = entries_.begin(); it != entries_.end(); ++it)
    if (it->key == key) {
      entries_.splice(entries_.begin(), entries_, it);
      return entries_.front().maps;
    }
  return nullptr;
}

void PhotonMapCache::Insert(const std::string& key, std::shared_ptr<const PhotonMaps> maps) {
  if (capacity_ == 0) return;
  std::lock_guard lock(mutex_);
  const uint64_t seed = maps ? maps->seed : 0;
  entries_.push_front(Entry{key, seed, std::move(maps)});
  while (entries_.size() > capacity_) entries_.pop_back();
}

void PhotonMapCache::Erase(const std::string& key) {
  std::lock_guard lock(mutex_);
  entries_.remove_if([&](const Entry& e) { return e.key == key; });
}

std::vector<uint64_t> PhotonMapCache::CachedSeeds() const {
  std::lock_guard lock(mutex_);
  std::vector<uint64_t> seeds;
  for (const Entry& e : entries_) seeds.push_back(e.seed);
  return seeds;
}

size_t PhotonMapCache::size() const {
  std::lock_guard lock(mutex_);
  return entries_.size();
}

}  // namespace pf
