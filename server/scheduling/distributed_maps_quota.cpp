// DistributedMaps, part: the map store's quota (distributed_maps.h, map_quota.h; docs/farm.md
// "The map store's quota").
#include <spdlog/spdlog.h>

#include <chrono>
#include <map>
#include <set>

#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/map_quota.h"
#include "server/scheduling/map_store_files.h"

namespace pf::server {
namespace fs = std::filesystem;

void DistributedMaps::TouchLocked(const std::string& key) const {
  if (options_.quota_bytes == 0) return;
  std::error_code ec;  // a touch that fails only makes the map look older
  fs::last_write_time(MapFileOf(options_.dir, key), fs::file_time_type::clock::now(), ec);
}

void DistributedMaps::EnforceQuotaNow() {
  if (options_.quota_bytes == 0 || !scheduler_) return;
  EnforceQuota(scheduler_->KnownJobs());
}

DistributedMaps::Evicted DistributedMaps::EnforceQuota(const std::vector<Scheduler::KnownJob>& jobs) {
  Evicted out;
  if (options_.quota_bytes == 0) return out;
  std::lock_guard quota_lock(quota_mu_);
  // Every map a live job may use, outside mu_ (hashing): jobs of one scene, settings and seed share
  // their maps (the same key for map 0), and reach those below their plan's PlanMapCount.
  std::set<std::string> known, active, live;
  std::map<std::string, std::pair<std::shared_ptr<const JobConfig>, uint64_t>> families;
  for (const Scheduler::KnownJob& job : jobs) {
    known.insert(job.id);
    if (!job.active) continue;
    active.insert(job.id);
    if (!MayDistributeMaps(*job.config)) continue;
    auto& [config, count] = families[DistributedMapKey(*job.config, MapSeed(job.config->seed, 0))];
    if (!config || PlanMapCount(job.config->plan) > count) {
      config = job.config;
      count = PlanMapCount(job.config->plan);
    }
  }
  for (const auto& [first, family] : families)
    for (uint64_t i = 0; i < family.second; ++i)
      live.insert(DistributedMapKey(*family.first, MapSeed(family.first->seed, i)));
  uint64_t total = 0;
  const std::vector<StoredMap> stored = ListStoredMaps(options_.dir.string(), &total);

  std::lock_guard lock(mu_);
  // Keys a live job has reached, and those of jobs registered since `jobs` was taken.
  for (const auto& [job_index, key] : keys_)
    if (active.count(job_index.first) || !known.count(job_index.first)) live.insert(key);
  const QuotaChoice choice =
      ChooseEvictions(stored, total, options_.quota_bytes, [&](const std::string& key) {
        if (live.count(key)) return true;
        auto m = maps_.find(key);
        return m != maps_.end() && (m->second.state == Map::State::kTracing ||
                                    m->second.state == Map::State::kBuilding || !m->second.waiting.empty());
      });
  const int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                             fs::file_time_type::clock::now().time_since_epoch())
                             .count();
  for (const StoredMap& m : choice.evict) {
    maps_.erase(m.key);
    on_disk_.erase(m.key);
    chunks_on_disk_.erase(m.key);
    RemoveWithTracers(MapFileOf(options_.dir, m.key));
    std::error_code ec;
    fs::remove_all(options_.dir / (m.key + ".chunks"), ec);
    ++out.maps;
    out.bytes += m.bytes;
    spdlog::info(
        "maps: evicted map {} ({} bytes, last used {:.0f} s ago): the store is over --maps-quota {} bytes",
        ShortKey(m.key), m.bytes, double(now_ns - m.last_used_ns) / 1e9, options_.quota_bytes);
  }
  counters_.maps_evicted += out.maps;
  counters_.bytes_evicted += out.bytes;
  out.bytes_after = choice.bytes_after;
  out.met = choice.met;
  if (!choice.met && !quota_warned_) {
    spdlog::warn(
        "maps: the store holds {} bytes, over --maps-quota {} bytes, and every map left is one a queued, "
        "running or paused job uses (or still tracing): kept; jobs go on (warned once until the quota is "
        "met)",
        choice.bytes_after, options_.quota_bytes);
  }
  quota_warned_ = !choice.met;
  return out;
}

}  // namespace pf::server
