#pragma once
// A render task's photon map when the coordinator built it (docs/farm.md, "Photon maps traced
// once"): from memory, from the disk cache (map_disk_cache.h), by FetchMap (coordinator_client.h
// checks every part; here the map's digest and seed, ReadNamedPhotonMaps; a refused transfer is
// fetched again), or traced here by ExecuteTask when the measured cost model says that is faster.
// The same map either way (docs/design.md, G1): only time is at stake.
//
// A fetched map is used only for a task whose Task.map names the digest it was fetched under: a
// map the coordinator traced again after a conviction has another (docs/farm.md "Result
// verification"), and a render task without Task.map traces its own.

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "common/photon/map_cache.h"
#include "photonfarm/v1/farm.pb.h"
#include "worker/coordinator_client.h"
#include "worker/leased_task.h"
#include "worker/map_disk_cache.h"
#include "worker/worker_options.h"

namespace pf::worker {

class MapObtainer {
 public:
  // `client` outlives the obtainer. Options: the memory and disk caches' sizes, the disk cache's
  // directory, the faults (the "fetch" kill point).
  MapObtainer(CoordinatorClient& client, const WorkerOptions& options);

  // The maps in memory (by MapCacheKey), shared with render threads that may outlive a hand-back.
  const std::shared_ptr<PhotonMapCache>& memory() const { return memory_; }

  // True if the map `ref` names is in memory under `cache_key`; a map there fetched under another
  // digest is dropped first (logged).
  bool InMemory(const std::string& cache_key, const photonfarm::v1::MapRef& ref, const std::string& ctx);
  // Puts the map `ref` names (of `photons`, for `map_seed`) into memory from disk or by FetchMap,
  // unless tracing it here is faster (logged); nullopt to go on rendering (ExecuteTask traces
  // what is not in memory). Unreachable: FetchMap found the coordinator away.
  std::optional<TaskEnd> Obtain(const std::string& cache_key, const photonfarm::v1::MapRef& ref,
                                const std::string& ctx, uint64_t photons, uint64_t map_seed);
  // A render task without Task.map: a map fetched for another task under `cache_key` is not
  // vouched for here, and is dropped.
  void ForgetFetched(const std::string& cache_key) { Forget(cache_key, ""); }

  // The cost model's tracing rate: `photons` traced and built in `seconds` with the worker's
  // threads. Not thread-safe (the pull loop's thread).
  void ObserveTracing(uint64_t photons, double seconds);

  uint64_t fetched() const { return fetched_.load(); }
  uint64_t from_disk() const { return from_disk_.load(); }

 private:
  void NoteFetched(const std::string& cache_key, const std::string& digest);
  // Drops the map of `cache_key` from memory if it was fetched under another digest than
  // `digest` ("" : any fetched map). True if dropped.
  bool Forget(const std::string& cache_key, const std::string& digest);
  // The map from the disk cache into memory (true), else the bad copy is removed.
  bool FromDisk(const std::string& cache_key, const photonfarm::v1::MapRef& ref, const std::string& ctx,
                uint64_t map_seed);
  // FetchMap until the map arrives whole and named (into memory and the disk cache) or the
  // attempts are used up (logged: traced here instead); Unreachable: the coordinator is away.
  std::optional<TaskEnd> Fetch(const std::string& cache_key, const photonfarm::v1::MapRef& ref,
                               const std::string& ctx, uint64_t map_seed);

  CoordinatorClient& client_;
  std::shared_ptr<WorkerFaults> faults_;
  std::shared_ptr<PhotonMapCache> memory_;
  MapDiskCache disk_;
  // Seconds per photon of tracing and building a map, bytes per second of fetches; 0 = not
  // measured yet.
  double seconds_per_photon_ = 0, bytes_per_second_ = 0;
  std::mutex mutex_;                                 // guards fetched_maps_
  std::map<std::string, std::string> fetched_maps_;  // cache key -> digest fetched under
  std::atomic<uint64_t> fetched_{0}, from_disk_{0};
};

}  // namespace pf::worker
