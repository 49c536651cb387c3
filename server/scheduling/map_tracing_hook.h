#pragma once
// The scheduler's hook for photon maps traced once (docs/farm.md "Photon maps traced
// once"): work that comes before render tasks (pieces of maps to trace) and a gate that keeps a
// render task out of the queue until its map is built. Implemented by DistributedMaps
// (distributed_maps.h); a Scheduler without one behaves as before.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/plan/task_plan.h"

namespace pf::server {

class Job;
struct Lease;
struct LeaseRequest;

// A lease on photons [photon_begin, photon_end) of a map (Task.trace_chunk).
struct TraceChunkLease {
  std::string map_key;
  uint64_t photon_begin = 0, photon_end = 0;
  uint32_t chunk_index = 0, chunk_count = 0;
};

class MapTracingHook {
 public:
  virtual ~MapTracingHook() = default;
  // Both are called under the scheduler's lock: they must not call back into the Scheduler and
  // must not do O(photons) work or I/O.
  // Whether `task` of `job` may be queued now (its map is built, or traced by its worker). If not,
  // the scheduler holds it back until Scheduler::ReleaseMap(job, map index).
  virtual bool RenderTaskReady(const Job& job, const TaskSpec& task) = 0;
  // A piece of a map to trace, as a lease with Lease::chunk set; served before render tasks.
  // Only of jobs `may_lease(job_id)` allows (worker health: not blocklisted for the job; null: any).
  using JobFilter = std::function<bool(const std::string& job_id)>;
  virtual std::optional<Lease> LeaseChunk(const LeaseRequest& request, double now,
                                          const JobFilter& may_lease) = 0;
  // Unlike the two above, called *outside* the scheduler's locks (it may delete files): a worker was
  // convicted (docs/farm.md "Result verification"): every stored map holding pieces it traced is
  // deleted and traced again, without its pieces. Returns the ids of the jobs whose render tasks
  // used such a built map (the scheduler restarts the active ones).
  virtual std::vector<std::string> WorkerConvicted(const std::string& /*worker_id*/) { return {}; }
};

}  // namespace pf::server
