#pragma once
// What the farm did, for people: the workers seen, in this life or a stored one (`pf workers`,
// the web status page) and each job's task events — which worker ran which task, retries,
// failures (`pf events JOB`). Bounded: a job keeps its newest kMaxEventsPerJob events. Stored
// (server/store/activity_store.h): the coordinator takes the changes every second (TakeChanges)
// and hands them to the store, and a restarted coordinator starts from what is stored (Restore);
// callers refused before reaching the farm are not stored. The scheduler records into it under its
// own lock; this class has its own mutex and never calls out, so the lock order is always
// scheduler → activity.

#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "photonfarm/v1/farm.pb.h"
#include "server/clock.h"
#include "server/store/activity_store.h"

namespace pf::server {

inline constexpr size_t kMaxEventsPerJob = 10000;
inline constexpr size_t kMaxWorkersKept = 4096;
// Callers refused before reaching the farm (WorkerRefused), one entry per address, kept apart from
// the workers: any number of unauthenticated calls then costs at most this many entries and never
// pushes a worker of the farm out. The least recently refused entry goes first, an entry without
// an address before any with one (made-up ids cannot push out the addresses).
inline constexpr size_t kMaxRefusedKept = 256;
// The distinct worker ids an address announced in refused calls, newest first, that are listed.
inline constexpr size_t kMaxRefusedIdsPerAddress = 4;
// A worker seen within this many seconds (and not offline) counts as live: --plan auto's worker
// count.
inline constexpr double kLiveSeconds = 60;

class FarmActivity {
 public:
  explicit FarmActivity(const Clock& clock) : clock_(clock) {}

  // A LeaseTask call from `worker_id` (its peer address, threads and version string).
  // `refused_reason` non-empty: the coordinator refused its lease (another build): listed as
  // refused with the reason and its version, so `pf workers` and the web page say why it gets no
  // work (docs/farm.md, Upgrades).
  void WorkerSeen(const std::string& worker_id, const std::string& peer, uint32_t threads,
                  const std::string& version, const std::string& refused_reason = "");
  // A WorkerService call refused before it reached the farm (auth.h: a wrong or missing token or
  // client certificate) from `address` (PeerHost: the connection's, not the caller's word; "" =
  // not known, refused before its address was), announcing `announced_id` (untrusted: made
  // printable and short; "" = none announced). Counted per address (where it is not known, per
  // announced id) and listed as refused, apart from the workers (kMaxRefusedKept): the address as
  // the peer, the ids it announced (kMaxRefusedIdsPerAddress, newest first; one an accepted worker
  // holds as "<id> (refused)"), the last reason and the number of refused calls. An id leaves its
  // address's entry (and its own entry without an address) when a LeaseTask under it from that
  // address is accepted; an entry goes with its last id. True for an entry's first refusal and for
  // a new reason (log it once; later ones are counted).
  bool WorkerRefused(const std::string& address, const std::string& announced_id, const std::string& reason);
  // Task events; `kind` is one of leased, merged, failed, expired, rejected, returned, revoked,
  // confirmed (a result above the job's bound reproduced by another worker, then merged); about a
  // map piece (task_id = the piece's index): piece-failed, piece-expired, piece-refused; about the worker in
  // this job (task_id, attempt: the failure that caused it): blocklisted, quarantined.
  void TaskEvent(const std::string& job_id, const std::string& kind, uint64_t task_id, uint32_t attempt,
                 const std::string& worker_id, const std::string& detail = "");
  // The merged result's statistics (photons per second of the worker).
  void WorkerStats(const std::string& worker_id, uint64_t photons_emitted, double seconds);
  // Worker health as the scheduler decided it (worker_health.h): lost or live again, blocklisted
  // for a job, quarantined until `until` (Clock::Now seconds) for `reason`.
  void WorkerLost(const std::string& worker_id, bool lost);
  // Said it is leaving (LeaveFarm): offline until its next call (false). A worker never listed
  // stays unlisted.
  void WorkerOffline(const std::string& worker_id, bool offline);
  void WorkerBlocklisted(const std::string& worker_id, const std::string& job_id);
  void WorkerQuarantined(const std::string& worker_id, double until, const std::string& reason);

  // A deleted job (pf delete): its events go, and it leaves the workers' blocklisted job lists.
  void ForgetJob(const std::string& job_id);

  // Persistence (docs/farm.md "Activity across restarts"). The events recorded and the workers
  // changed since the last call (a worker only polling: every kLastSeenStoreSeconds), and the
  // workers evicted; ReturnChanges puts back a batch the store could not take (the newest
  // kMaxPendingEvents events are kept). Restore (at start, before any call) loads a store's
  // records, the kMaxWorkersKept most recently seen workers (the others are forgotten): their
  // counts as they were, seen when they were last seen, none busy (leases end with a coordinator)
  // and each lost (or offline) until it polls again; quarantine and blocklists are left out, as
  // this life's worker health starts without them (worker_health.h).
  ActivityRecords TakeChanges();
  void ReturnChanges(ActivityRecords records);
  void Restore(const ActivityRecords& records);

  std::vector<photonfarm::v1::WorkerInfo> Workers() const;
  // Events of `job_id`, oldest first; `dropped` = older events no longer kept. Empty for a job
  // with no events (the caller checks that the job exists).
  std::vector<photonfarm::v1::TaskEvent> Events(const std::string& job_id, uint64_t* dropped = nullptr) const;

 private:
  struct Worker {
    photonfarm::v1::WorkerInfo info;
    double last_seen = 0;
    double quarantined_until = 0;
    // Restored from the store (Restore): its lost and offline flags are the last life's, which
    // this life's worker health never set, so its first accepted poll clears them.
    bool restored = false;
    // Changed since it was last taken (TakeChanges); a poll alone changes only last_seen, which is
    // taken at most every kLastSeenStoreSeconds.
    bool dirty = true;
    double stored_last_seen = -1e300;
  };
  static constexpr double kLastSeenStoreSeconds = 30;
  struct JobEvents {
    std::deque<photonfarm::v1::TaskEvent> events;
    uint64_t dropped = 0;
  };
  struct RefusedAddress {
    photonfarm::v1::WorkerInfo info;  // refused, its reason and count
    std::deque<std::string> ids;      // announced, distinct, newest first
    double last_seen = 0;
  };
  Worker& WorkerLocked(const std::string& worker_id);
  static constexpr size_t kMaxPendingEvents = 100000;

  const Clock& clock_;
  mutable std::mutex mu_;
  std::map<std::string, Worker> workers_;
  // WorkerRefused's entries, by {address, ""}, or {"", announced id} where the address is not known.
  std::map<std::pair<std::string, std::string>, RefusedAddress> refused_;
  std::map<std::string, JobEvents> events_;
  std::vector<ActivityRecords::Event> pending_events_;  // recorded, not yet taken (TakeChanges)
  std::vector<std::string> forgotten_workers_;          // evicted since the last TakeChanges
};

}  // namespace pf::server
