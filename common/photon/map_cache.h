#pragma once
// Photon maps kept between tasks of a process (pf-worker, a local plan render).

#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/photon/photon_maps.h"

namespace pf {

// LRU cache of photon maps by (scene key, map fingerprint, map seed). Thread-safe.
class PhotonMapCache {
 public:
  explicit PhotonMapCache(size_t capacity = 4) : capacity_(capacity) {}
  std::shared_ptr<const PhotonMaps> Find(const std::string& key);
  void Insert(const std::string& key, std::shared_ptr<const PhotonMaps> maps);
  // Drops the maps of `key` (a map fetched under a digest the coordinator no longer names:
  // worker/map_obtainer.cpp).
  void Erase(const std::string& key);
  std::vector<uint64_t> CachedSeeds() const;
  size_t size() const;

 private:
  struct Entry {
    std::string key;
    uint64_t seed;
    std::shared_ptr<const PhotonMaps> maps;
  };
  mutable std::mutex mutex_;
  std::list<Entry> entries_;  // most recent first
  size_t capacity_;
};

}  // namespace pf
