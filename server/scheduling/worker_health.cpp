#include "server/scheduling/worker_health.h"

#include <algorithm>
#include <cstdio>

#include "server/scheduling/farm_activity.h"

namespace pf::server {

WorkerHealth::Worker& WorkerHealth::WorkerOf(const std::string& worker_id, double now) {
  auto it = workers_.find(worker_id);
  if (it != workers_.end()) return it->second;
  if (workers_.size() >= kMaxWorkersKept) {
    // Bounded like FarmActivity: forget the longest-silent worker, a quarantined one last (made-up
    // worker ids must not shed a quarantine).
    auto victim = workers_.end();
    for (auto w = workers_.begin(); w != workers_.end(); ++w) {
      if (victim == workers_.end()) {
        victim = w;
        continue;
      }
      const bool wq = w->second.quarantined_until > now, vq = victim->second.quarantined_until > now;
      if (wq != vq ? vq : w->second.last_call < victim->second.last_call) victim = w;
    }
    workers_.erase(victim);
  }
  Worker& w = workers_[worker_id];
  w.last_call = now;
  return w;
}

bool WorkerHealth::Polled(const std::string& worker_id, double now) {
  if (worker_id.empty()) return false;
  WorkerOf(worker_id, now);
  return Heard(worker_id, now);
}

bool WorkerHealth::Heard(const std::string& worker_id, double now) {
  auto it = workers_.find(worker_id);
  if (it == workers_.end()) return false;
  Worker& w = it->second;
  w.last_call = std::max(w.last_call, now);
  const bool was_lost = w.lost;
  w.lost = false;
  w.left = false;
  return was_lost;
}

bool WorkerHealth::LeaseRanOut(const std::string& worker_id, double renewed, double now) {
  auto it = workers_.find(worker_id);
  if (it == workers_.end() || it->second.lost || it->second.left) return false;
  // The lease was renewed at the same clock reading as the worker's call that renewed it; a
  // millisecond of slack absorbs the rounding of deadline − lease_seconds.
  if (it->second.last_call > renewed + 1e-3 || now < renewed) return false;
  it->second.lost = true;
  return true;
}

std::vector<std::pair<std::string, double>> WorkerHealth::MarkSilentLost(double now) {
  std::vector<std::pair<std::string, double>> lost;
  for (auto& [id, w] : workers_)
    if (!w.lost && !w.left && now - w.last_call > options_.lost_seconds) {
      w.lost = true;
      lost.emplace_back(id, now - w.last_call);
    }
  return lost;
}

bool WorkerHealth::Left(const std::string& worker_id) {
  auto it = workers_.find(worker_id);
  if (it == workers_.end()) return false;
  it->second.left = true;
  it->second.lost = false;
  return true;
}

bool WorkerHealth::HasLeft(const std::string& worker_id) const {
  auto it = workers_.find(worker_id);
  return it != workers_.end() && it->second.left;
}

bool WorkerHealth::Lost(const std::string& worker_id) const {
  auto it = workers_.find(worker_id);
  return it != workers_.end() && it->second.lost;
}

WorkerHealth::FailureOutcome WorkerHealth::RecordFailure(const std::string& job_id,
                                                         const std::string& worker_id,
                                                         const std::string& reason, double now,
                                                         bool convicted) {
  FailureOutcome out;
  if (worker_id.empty()) return out;
  JobHealth& job = jobs_[job_id];
  out.failed_attempts = ++job.failures[worker_id];
  if (out.failed_attempts == 1) ++WorkerOf(worker_id, now).active_jobs_failed;
  if (auto b = job.blocklisted.find(worker_id); b != job.blocklisted.end()) {
    // Leases it held before it was blocklisted may still fail.
    b->second.failed_attempts = out.failed_attempts;
    b->second.last_error = reason;
    return out;
  }
  if (!convicted && (options_.blocklist_failures == 0 || out.failed_attempts < options_.blocklist_failures))
    return out;
  job.blocklisted[worker_id] = Blocklisted{out.failed_attempts, reason};
  out.blocklisted = true;
  if (options_.quarantine_jobs == 0) return out;
  Worker& w = WorkerOf(worker_id, now);
  w.blocklistings.emplace_back(now, job_id);
  while (!w.blocklistings.empty() && w.blocklistings.front().first < now - options_.quarantine_seconds)
    w.blocklistings.pop_front();
  if (w.blocklistings.size() < options_.quarantine_jobs) return out;
  char window[32];
  std::snprintf(window, sizeof(window), "%.0f", options_.quarantine_seconds);
  out.quarantine_reason =
      "blocklisted by " + std::to_string(w.blocklistings.size()) + " jobs within " + window + " s (";
  for (size_t i = 0; i < w.blocklistings.size(); ++i)
    out.quarantine_reason += (i ? ", " : "") + w.blocklistings[i].second;
  out.quarantine_reason += ")";
  // The jobs that caused it do not count again: the next quarantine takes as many new ones.
  w.blocklistings.clear();
  w.quarantined_until = now + options_.quarantine_seconds;
  out.quarantined = true;
  return out;
}

bool WorkerHealth::Blocklist(const std::string& job_id, const std::string& worker_id,
                             const std::string& reason, double now) {
  if (worker_id.empty()) return false;
  JobHealth& job = jobs_[job_id];
  if (job.blocklisted.count(worker_id)) return false;
  // Counted as a failure in the job, so that the healthy-worker fast path (FailedInActiveJob)
  // does not skip its blocklist.
  const uint32_t failures = ++job.failures[worker_id];
  if (failures == 1) ++WorkerOf(worker_id, now).active_jobs_failed;
  job.blocklisted[worker_id] = Blocklisted{failures, reason};
  return true;
}

bool WorkerHealth::IsBlocklisted(const std::string& job_id, const std::string& worker_id) const {
  auto it = jobs_.find(job_id);
  return it != jobs_.end() && it->second.blocklisted.count(worker_id) > 0;
}

bool WorkerHealth::FailedInActiveJob(const std::string& worker_id) const {
  auto it = workers_.find(worker_id);
  return it != workers_.end() && it->second.active_jobs_failed > 0;
}

bool WorkerHealth::Quarantined(const std::string& worker_id, double now) const {
  auto it = workers_.find(worker_id);
  return it != workers_.end() && it->second.quarantined_until > now;
}

const std::map<std::string, WorkerHealth::Blocklisted>& WorkerHealth::BlocklistOf(
    const std::string& job_id) const {
  static const std::map<std::string, Blocklisted> kNone;
  auto it = jobs_.find(job_id);
  return it == jobs_.end() ? kNone : it->second.blocklisted;
}

bool WorkerHealth::AnyLiveWorkerMayRun(const std::string& job_id) const {
  const auto& blocklist = BlocklistOf(job_id);
  for (const auto& [id, w] : workers_)
    if (!w.lost && !w.left && !blocklist.count(id)) return true;
  return false;
}

bool WorkerHealth::AnyLiveWorker(const std::function<bool(const std::string&)>& eligible, double now) const {
  for (const auto& [id, w] : workers_)
    if (!w.lost && !w.left && w.quarantined_until <= now && eligible(id)) return true;
  return false;
}

void WorkerHealth::ForgetJob(const std::string& job_id) {
  JobEnded(job_id);
  jobs_.erase(job_id);
}

void WorkerHealth::JobEnded(const std::string& job_id) {
  auto it = jobs_.find(job_id);
  if (it == jobs_.end()) return;
  for (const auto& [worker, failures] : it->second.failures)
    if (auto w = workers_.find(worker); w != workers_.end() && w->second.active_jobs_failed > 0)
      --w->second.active_jobs_failed;
  if (it->second.blocklisted.empty())
    jobs_.erase(it);
  else
    it->second.failures.clear();
}

}  // namespace pf::server
