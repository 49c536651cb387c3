#pragma once
// Where the farm's activity — each job's task events and the workers' statistics (`pf events`,
// `pf workers`, the web page; server/scheduling/farm_activity.h) — outlives a coordinator restart
// (docs/farm.md "Activity across restarts"). FarmActivity hands its changes over in batches, as
// serialized records this layer does not read; SqliteStore keeps them beside the jobs, at most
// `max_events_per_job` events per job, and removes a job's events with the job (JobStore::DeleteJob).
//
// A batch is durable when SaveActivity returns (one transaction) or it throws (StorageError on a full
// or failing disk): the caller keeps it and tries again. What a SIGKILL catches between two batches
// (at most a second of events) is lost: activity is for people, not for the image.

#include <cstdint>
#include <string>
#include <vector>

namespace pf::server {

struct ActivityRecords {
  struct Event {
    std::string job_id;
    std::string bytes;  // a photonfarm.v1.TaskEvent
  };
  struct Worker {
    std::string worker_id;
    std::string bytes;  // a photonfarm.v1.WorkerInfo
    int64_t last_seen_unix_ms = 0;
    double quarantined_until_unix_s = 0;  // 0: not quarantined
  };
  std::vector<Event> events;                   // in the order they happened
  std::vector<Worker> workers;                 // each replaces the stored worker of its id
  std::vector<std::string> forgotten_workers;  // ids whose stored worker goes
  bool empty() const { return events.empty() && workers.empty() && forgotten_workers.empty(); }
};

class ActivityStore {
 public:
  virtual ~ActivityStore() = default;
  // Appends the events of jobs that have a row (a job deleted meanwhile keeps none), replaces the
  // workers and removes the forgotten ones, in one transaction; keeps each job's newest
  // `max_events_per_job` events.
  virtual void SaveActivity(const ActivityRecords& records, size_t max_events_per_job) = 0;
  // Everything stored (events of jobs without a row are removed first): events oldest first,
  // workers by id.
  virtual ActivityRecords LoadActivity() = 0;
};

}  // namespace pf::server
