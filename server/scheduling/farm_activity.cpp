#include "server/scheduling/farm_activity.h"

#include <algorithm>
#include <set>

#include "proto/limits.h"
#include "server/peer_host.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

// A refused entry's address as it is stored and listed: printable, at most kMaxEchoBytes.
std::string RefusedAddressKey(const std::string& address) {
  return limits::Printable(address, limits::kMaxEchoBytes);
}

}  // namespace

FarmActivity::Worker& FarmActivity::WorkerLocked(const std::string& worker_id) {
  auto it = workers_.find(worker_id);
  if (it != workers_.end()) {
    it->second.dirty = true;  // every caller but WorkerSeen changes it (WorkerSeen decides itself)
    return it->second;
  }
  if (workers_.size() >= kMaxWorkersKept) {  // forget the longest-silent worker
    auto oldest = workers_.begin();
    for (auto w = workers_.begin(); w != workers_.end(); ++w)
      if (w->second.last_seen < oldest->second.last_seen) oldest = w;
    forgotten_workers_.push_back(oldest->first);
    workers_.erase(oldest);
  }
  Worker& w = workers_[worker_id];
  w.info.set_worker_id(worker_id);
  w.last_seen = clock_.Now();
  return w;
}

void FarmActivity::WorkerSeen(const std::string& worker_id, const std::string& peer, uint32_t threads,
                              const std::string& version, const std::string& refused_reason) {
  std::lock_guard lock(mu_);
  const auto known = workers_.find(worker_id);
  const bool was_dirty = known == workers_.end() || known->second.dirty;
  Worker& w = WorkerLocked(worker_id);
  const std::string before = w.info.SerializeAsString();
  w.info.set_peer(peer);
  w.info.set_threads(threads);
  w.info.set_version(version);
  w.info.set_refused(!refused_reason.empty());
  w.info.set_refused_reason(refused_reason);
  w.info.set_refused_calls(refused_reason.empty() ? 0 : w.info.refused_calls() + 1);
  w.last_seen = clock_.Now();
  if (w.restored && refused_reason.empty()) {
    w.restored = false;
    w.info.set_lost(false);
    w.info.set_offline(false);
  }
  w.dirty = was_dirty || w.info.SerializeAsString() != before;
  if (refused_reason.empty() && !refused_.empty()) {  // its credential works now (polls: usually none)
    // As its refused calls announced it (pf-worker-id carries at most kMaxAnnouncedIdBytes).
    const std::string announced = limits::AnnouncedWorkerId(worker_id);
    refused_.erase({"", announced});  // refused where its address was not known
    const auto refused = refused_.find({RefusedAddressKey(PeerHost(peer)), ""});
    if (refused != refused_.end()) {
      std::deque<std::string>& ids = refused->second.ids;
      ids.erase(std::remove(ids.begin(), ids.end(), announced), ids.end());
      if (ids.empty()) refused_.erase(refused);
    }
  }
}

bool FarmActivity::WorkerRefused(const std::string& address, const std::string& announced_id,
                                 const std::string& reason) {
  std::string id = limits::AnnouncedWorkerId(announced_id);  // untrusted: printable and short
  if (id.empty()) id = "(no worker id)";
  const std::string where = RefusedAddressKey(address);
  // Per address; where it is not known, per announced id.
  const std::pair<std::string, std::string> key{where, where.empty() ? id : ""};
  std::lock_guard lock(mu_);
  auto it = refused_.find(key);
  const bool first = it == refused_.end() || it->second.info.refused_reason() != reason;
  if (it == refused_.end()) {
    if (refused_.size() >= kMaxRefusedKept) {
      // Forget the least recently refused entry, one without an address first: callers without an
      // address choose their ids, so their made-up ids must not push out the addresses.
      auto oldest = refused_.end();
      for (auto r = refused_.begin(); r != refused_.end(); ++r) {
        const bool unaddressed = r->first.first.empty();
        if (oldest == refused_.end() || unaddressed > oldest->first.first.empty() ||
            (unaddressed == oldest->first.first.empty() && r->second.last_seen < oldest->second.last_seen))
          oldest = r;
      }
      refused_.erase(oldest);
    }
    it = refused_.emplace(key, RefusedAddress{}).first;
    it->second.info.set_peer(where);
    it->second.info.set_refused(true);
  }
  RefusedAddress& r = it->second;
  r.ids.erase(std::remove(r.ids.begin(), r.ids.end(), id), r.ids.end());
  r.ids.push_front(id);
  if (r.ids.size() > kMaxRefusedIdsPerAddress) r.ids.pop_back();
  r.info.set_refused_reason(reason);
  r.info.set_refused_calls(r.info.refused_calls() + 1);
  r.last_seen = clock_.Now();
  return first;
}

void FarmActivity::TaskEvent(const std::string& job_id, const std::string& kind, uint64_t task_id,
                             uint32_t attempt, const std::string& worker_id, const std::string& detail) {
  std::lock_guard lock(mu_);
  JobEvents& je = events_[job_id];
  v1::TaskEvent& e = je.events.emplace_back();
  e.set_unix_ms(clock_.UnixMillis());
  e.set_kind(kind);
  e.set_task_id(task_id);
  e.set_attempt(attempt);
  e.set_worker_id(worker_id);
  e.set_detail(detail);
  pending_events_.push_back({job_id, e.SerializeAsString()});
  if (je.events.size() > kMaxEventsPerJob) {
    je.events.pop_front();
    ++je.dropped;
  }
  if (worker_id.empty()) return;
  Worker& w = WorkerLocked(worker_id);
  if (kind == "leased") {
    w.info.set_busy(true);
    w.info.set_current_job_id(job_id);
    w.info.set_current_task_id(task_id);
    w.last_seen = clock_.Now();
    return;
  }
  const bool piece = kind.starts_with("piece-");  // task_id is a map piece's index, not a task's
  if (piece) {
    w.info.set_tasks_failed(w.info.tasks_failed() + 1);
    return;
  }
  if (kind == "blocklisted" || kind == "quarantined") return;  // about the worker, not the task
  // Any other event ends the worker's hold on this task (if it still holds it).
  if (w.info.busy() && w.info.current_job_id() == job_id && w.info.current_task_id() == task_id) {
    w.info.set_busy(false);
    w.info.clear_current_job_id();
    w.info.set_current_task_id(0);
  }
  if (kind == "merged") {
    w.info.set_tasks_done(w.info.tasks_done() + 1);
    w.last_seen = clock_.Now();
  } else if (kind == "failed" || kind == "expired" || kind == "rejected") {
    w.info.set_tasks_failed(w.info.tasks_failed() + 1);
  }
}

void FarmActivity::WorkerStats(const std::string& worker_id, uint64_t photons_emitted, double seconds) {
  if (worker_id.empty()) return;
  std::lock_guard lock(mu_);
  Worker& w = WorkerLocked(worker_id);
  w.info.set_photons_emitted(w.info.photons_emitted() + photons_emitted);
  if (seconds > 0 && seconds < 1e9) w.info.set_busy_seconds(w.info.busy_seconds() + seconds);
  w.info.set_photons_per_second(
      w.info.busy_seconds() > 0 ? double(w.info.photons_emitted()) / w.info.busy_seconds() : 0.0);
}

void FarmActivity::WorkerOffline(const std::string& worker_id, bool offline) {
  std::lock_guard lock(mu_);
  auto it = workers_.find(worker_id);
  if (it == workers_.end() || it->second.info.offline() == offline) return;
  it->second.dirty = true;
  it->second.info.set_offline(offline);
  if (offline) {
    it->second.info.set_lost(false);
    it->second.info.set_busy(false);
    it->second.info.clear_current_job_id();
    it->second.info.set_current_task_id(0);
  }
}

void FarmActivity::WorkerLost(const std::string& worker_id, bool lost) {
  if (worker_id.empty()) return;
  std::lock_guard lock(mu_);
  WorkerLocked(worker_id).info.set_lost(lost);
}

void FarmActivity::ForgetJob(const std::string& job_id) {
  std::lock_guard lock(mu_);
  events_.erase(job_id);
  std::erase_if(pending_events_, [&](const ActivityRecords::Event& e) { return e.job_id == job_id; });
  for (auto& [id, w] : workers_) {
    auto* ids = w.info.mutable_blocklisted_job_ids();
    for (int i = 0; i < ids->size();)
      if (ids->Get(i) == job_id) {
        ids->DeleteSubrange(i, 1);
        w.dirty = true;
      } else {
        ++i;
      }
  }
}

void FarmActivity::WorkerBlocklisted(const std::string& worker_id, const std::string& job_id) {
  if (worker_id.empty()) return;
  std::lock_guard lock(mu_);
  Worker& w = WorkerLocked(worker_id);
  for (const std::string& id : w.info.blocklisted_job_ids())
    if (id == job_id) return;
  w.info.add_blocklisted_job_ids(job_id);
}

void FarmActivity::WorkerQuarantined(const std::string& worker_id, double until, const std::string& reason) {
  if (worker_id.empty()) return;
  std::lock_guard lock(mu_);
  Worker& w = WorkerLocked(worker_id);
  w.quarantined_until = until;
  w.info.set_quarantine_reason(reason);
}

ActivityRecords FarmActivity::TakeChanges() {
  std::lock_guard lock(mu_);
  ActivityRecords out;
  out.events.swap(pending_events_);
  out.forgotten_workers.swap(forgotten_workers_);
  const double now = clock_.Now();
  const int64_t unix_ms = clock_.UnixMillis();
  for (auto& [id, w] : workers_) {
    if (!w.dirty && w.last_seen < w.stored_last_seen + kLastSeenStoreSeconds) continue;
    w.dirty = false;
    w.stored_last_seen = w.last_seen;
    out.workers.push_back(
        {.worker_id = id,
         .bytes = w.info.SerializeAsString(),
         .last_seen_unix_ms = unix_ms - int64_t((now - w.last_seen) * 1000.0),
         .quarantined_until_unix_s =
             w.quarantined_until > now ? double(unix_ms) / 1000.0 + (w.quarantined_until - now) : 0.0});
  }
  return out;
}

void FarmActivity::ReturnChanges(ActivityRecords records) {
  std::lock_guard lock(mu_);
  // Older than what was recorded since: in front.
  records.events.insert(records.events.end(), std::make_move_iterator(pending_events_.begin()),
                        std::make_move_iterator(pending_events_.end()));
  pending_events_ = std::move(records.events);
  if (pending_events_.size() > kMaxPendingEvents)
    pending_events_.erase(pending_events_.begin(),
                          pending_events_.begin() + ptrdiff_t(pending_events_.size() - kMaxPendingEvents));
  for (const ActivityRecords::Worker& stored : records.workers)
    if (auto it = workers_.find(stored.worker_id); it != workers_.end()) it->second.dirty = true;
  forgotten_workers_.insert(forgotten_workers_.end(), records.forgotten_workers.begin(),
                            records.forgotten_workers.end());
}

void FarmActivity::Restore(const ActivityRecords& records) {
  std::lock_guard lock(mu_);
  const double now = clock_.Now();
  const int64_t unix_ms = clock_.UnixMillis();
  for (const ActivityRecords::Event& stored : records.events) {
    v1::TaskEvent e;
    if (!e.ParseFromString(stored.bytes)) continue;  // a record of another build: not shown
    JobEvents& je = events_[stored.job_id];
    je.events.push_back(std::move(e));
    if (je.events.size() > kMaxEventsPerJob) {
      je.events.pop_front();
      ++je.dropped;
    }
  }
  // The most recently seen first: those beyond kMaxWorkersKept are forgotten, here and in the store.
  std::vector<const ActivityRecords::Worker*> by_recency;
  for (const ActivityRecords::Worker& stored : records.workers) by_recency.push_back(&stored);
  std::stable_sort(by_recency.begin(), by_recency.end(),
                   [](const auto* a, const auto* b) { return a->last_seen_unix_ms > b->last_seen_unix_ms; });
  for (const ActivityRecords::Worker* stored : by_recency) {
    Worker w;
    if (workers_.size() >= kMaxWorkersKept || !w.info.ParseFromString(stored->bytes)) {
      forgotten_workers_.push_back(stored->worker_id);
      continue;
    }
    w.info.set_worker_id(stored->worker_id);
    w.info.set_busy(false);  // its lease, if any, ended with the coordinator
    w.info.clear_current_job_id();
    w.info.set_current_task_id(0);
    // This life's worker health (worker_health.h) starts without quarantines and blocklists: the
    // list shows what is enforced.
    w.info.clear_quarantine_reason();
    w.info.clear_blocklisted_job_ids();
    // Not heard from in this life: lost (or offline, if it had left) until it polls.
    if (!w.info.offline()) w.info.set_lost(true);
    w.restored = true;
    w.last_seen = now - std::max<double>(0.0, double(unix_ms - stored->last_seen_unix_ms) / 1000.0);
    w.stored_last_seen = w.last_seen;
    w.dirty = false;
    workers_[stored->worker_id] = std::move(w);
  }
}

std::vector<v1::WorkerInfo> FarmActivity::Workers() const {
  std::lock_guard lock(mu_);
  const double now = clock_.Now();
  std::vector<v1::WorkerInfo> out;
  out.reserve(workers_.size() + refused_.size());
  for (const auto& [id, w] : workers_) {
    out.push_back(w.info);
    v1::WorkerInfo& info = out.back();
    info.set_seconds_since_seen(std::max(0.0, now - w.last_seen));
    info.set_quarantined(w.quarantined_until > now);
    if (info.quarantined())
      info.set_quarantine_seconds_left(w.quarantined_until - now);
    else
      info.clear_quarantine_reason();
  }
  std::set<std::string> announced_by_workers;  // the workers' ids as a refused call announces them
  if (!refused_.empty())
    for (const auto& [id, w] : workers_) announced_by_workers.insert(limits::AnnouncedWorkerId(id));
  for (const auto& [key, r] : refused_) {
    out.push_back(r.info);
    std::string ids;
    for (const std::string& id : r.ids) {
      // An id any caller may announce: a worker's own entry keeps saying what that worker does.
      ids += (ids.empty() ? "" : ", ") + id + (announced_by_workers.count(id) ? " (refused)" : "");
    }
    out.back().set_worker_id(ids);
    out.back().set_seconds_since_seen(std::max(0.0, now - r.last_seen));
  }
  return out;
}

std::vector<v1::TaskEvent> FarmActivity::Events(const std::string& job_id, uint64_t* dropped) const {
  std::lock_guard lock(mu_);
  auto it = events_.find(job_id);
  if (dropped) *dropped = it == events_.end() ? 0 : it->second.dropped;
  if (it == events_.end()) return {};
  return {it->second.events.begin(), it->second.events.end()};
}

}  // namespace pf::server
