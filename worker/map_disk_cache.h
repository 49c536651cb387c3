#pragma once
// The worker's photon maps on disk (docs/farm.md, "Photon maps traced once"): the byte form of built maps
// (common/photon/photon_maps_bytes.h) by content address (MapRef.map_key), so that a restarted
// worker, or a later job with the same scene, settings and seed, fetches nothing.
//
// * Atomic writes (common/core/atomic_file.h): a file is whole or absent.
// * Verified on load by the caller: the bytes' own digest (DeserializePhotonMaps) and the
//   coordinator's MapRef.digest; a file that fails is Removed and the map fetched again.
// * Size limit: after each Put, the least recently used files (by modification time, which Get
//   refreshes) are deleted until the total is within `max_bytes`; a map larger than the limit
//   is not kept. Not shared between processes: one directory per worker.

#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>

namespace pf::worker {

class MapDiskCache {
 public:
  MapDiskCache(std::filesystem::path dir, uint64_t max_bytes);

  // A valid key is 64 lowercase hex digits (std::invalid_argument otherwise: never a path).
  std::optional<std::string> Get(const std::string& key);
  void Put(const std::string& key, std::string_view bytes);
  void Remove(const std::string& key);
  uint64_t total_bytes();
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path PathOf(const std::string& key) const;
  void EvictLocked();

  std::filesystem::path dir_;
  uint64_t max_bytes_;
  std::mutex mu_;
};

}  // namespace pf::worker
