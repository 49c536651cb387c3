#include "server/scheduling/map_quota.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <limits>
#include <map>

namespace pf::server {
namespace fs = std::filesystem;

QuotaChoice ChooseEvictions(std::vector<StoredMap> stored, uint64_t total_bytes, uint64_t quota_bytes,
                            const std::function<bool(const std::string& key)>& live) {
  std::sort(stored.begin(), stored.end(), [](const StoredMap& a, const StoredMap& b) {
    return a.last_used_ns != b.last_used_ns ? a.last_used_ns < b.last_used_ns : a.key < b.key;
  });
  QuotaChoice choice;
  choice.bytes_after = total_bytes;
  for (const StoredMap& m : stored) {
    if (choice.bytes_after <= quota_bytes) break;
    if (live(m.key)) continue;
    choice.bytes_after -= std::min(choice.bytes_after, m.bytes);
    choice.evict.push_back(m);
  }
  choice.met = choice.bytes_after <= quota_bytes;
  return choice;
}

namespace {

bool IsMapKey(const std::string& name) {
  return name.size() == 64 && std::all_of(name.begin(), name.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

int64_t Nanos(fs::file_time_type t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

}  // namespace

std::vector<StoredMap> ListStoredMaps(const std::string& dir, uint64_t* total_bytes) {
  std::map<std::string, StoredMap> maps;
  uint64_t total = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code fec;
    if (!it->is_regular_file(fec)) continue;
    const uint64_t size = it->file_size(fec);
    if (fec) continue;
    total += size;
    // <key>.pfmaps, <key>.pfmaps.by, <key>.chunks/BEGIN-END[.by]: the key is the top entry's name
    // up to its first dot.
    const fs::path relative = it->path().lexically_relative(dir);
    const std::string top = relative.begin()->string();
    const std::string key = top.substr(0, top.find('.'));
    if (!IsMapKey(key)) continue;
    auto [at, added] = maps.try_emplace(key);
    StoredMap& m = at->second;
    // The file clock's epoch is not the Unix one: its times may be negative.
    if (added) m.last_used_ns = std::numeric_limits<int64_t>::min();
    m.key = key;
    m.bytes += size;
    m.last_used_ns = std::max(m.last_used_ns, Nanos(it->last_write_time(fec)));
  }
  if (total_bytes) *total_bytes = total;
  std::vector<StoredMap> out;
  out.reserve(maps.size());
  for (auto& [key, m] : maps) out.push_back(std::move(m));
  return out;
}

}  // namespace pf::server
