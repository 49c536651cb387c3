#pragma once
// The map store's quota (pf-coordinator --maps-quota; docs/farm.md "The map store's quota"): which
// stored maps to evict when <data-dir>/maps holds more than the quota. Least recently used first —
// a map's use is the modification time of its files: set when it is stored and touched whenever
// it is served (FetchMap) or reused from disk by a new job, so the order survives a restart
// (atime is not used: relatime and noatime mounts do not keep it). A live map (one a queued,
// running or paused job may still use, or one still tracing or building) is never chosen; if the
// quota cannot be met without one, what can go goes and the rest stays (`met` false).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace pf::server {

// One map's files in the store: <key>.pfmaps, its `.by` record and <key>.chunks/ (pieces).
struct StoredMap {
  std::string key;
  uint64_t bytes = 0;
  int64_t last_used_ns = 0;  // the newest modification time of its files (file clock, ns)
};

struct QuotaChoice {
  std::vector<StoredMap> evict;  // least recently used first
  uint64_t bytes_after = 0;      // what the store holds once they are gone
  bool met = true;               // bytes_after <= quota
};

// `total_bytes`: the whole store (may hold files no StoredMap names); `live(key)`: may not be evicted.
QuotaChoice ChooseEvictions(std::vector<StoredMap> stored, uint64_t total_bytes, uint64_t quota_bytes,
                            const std::function<bool(const std::string& key)>& live);

// The maps in a store folder (keys of 64 hex digits), with their bytes and last use, and the bytes
// of every file in it.
std::vector<StoredMap> ListStoredMaps(const std::string& dir, uint64_t* total_bytes);

}  // namespace pf::server
