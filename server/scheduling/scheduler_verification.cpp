// The Scheduler's part in result verification (result_verification.h; docs/farm.md "Result
// verification"): verification leases, their results, the referee's verdicts and convictions. The
// locks are scheduler.h's: image_mu before mu_, O(pixels) work under neither.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <map>

#include "proto/limits.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {

namespace {

using Verification = ResultVerification::Verification;

bool FailedBefore(const Verification& v, const std::string& worker) {
  return std::find(v.failed_verifiers.begin(), v.failed_verifiers.end(), worker) != v.failed_verifiers.end();
}

std::string Who(const std::string& worker) {
  return limits::Quote(worker, limits::kMaxWorkerIdBytes);
}

}  // namespace

void Scheduler::SetReferee(RefereeHook* referee) {
  std::lock_guard lock(mu_);
  referee_ = referee;
}

void Scheduler::SetVerificationRandomForTest(std::function<double()> uniform) {
  std::lock_guard lock(mu_);
  verification_.SetRandomForTest(std::move(uniform));
}

bool Scheduler::IsVerificationLease(const std::string& lease_id) {
  std::lock_guard lock(mu_);
  return verification_.FindLease(lease_id) != nullptr;
}

void Scheduler::AddVerificationLocked(Job& job, uint64_t task_id, const std::string& worker,
                                      const std::string& digest, const std::string& reason, Effects& fx) {
  Verification& v = verification_.Add(job, task_id, worker, digest, reason);
  v.epoch = job.epoch();
  v.config = job.shared_config();
  spdlog::info("job {} task {}: the result of worker {} is to be verified by another worker ({})", job.id(),
               task_id, Who(worker), reason);
  Touch(job, fx);
}

std::optional<Lease> Scheduler::LeaseVerificationLocked(const LeaseRequest& request, double now, Effects& fx,
                                                        bool* passed) {
  const std::string& worker = request.worker_id;
  bool skipped = false;
  // Another worker than the one whose result it checks, not blocklisted for the job, and not one
  // that failed this verification already.
  Verification* v = verification_.NextQueued([&](const Verification& c) {
    const bool ok = c.job->active() && c.digests.front().first != worker && !FailedBefore(c, worker) &&
                    !health_.IsBlocklisted(c.job->id(), worker);
    skipped = skipped || !ok;
    return ok;
  });
  if (!v) {
    if (skipped && passed) *passed = true;
    return std::nullopt;
  }
  Job& job = *v->job;
  // An ordinary task lease to the worker: the attempt continues the task's numbering, as a retry's.
  const uint32_t attempt = job.runtime(v->task_id).attempts + v->leases + 1;
  verification_.Leased(*v, LeaseTable::MakeId(job.id(), v->task_id, attempt), worker,
                       now + options_.lease_seconds);
  ++counters_.verification_leases;
  Touch(job, fx);
  const std::string& original = v->digests.front().first;
  spdlog::info("job {} task {}: verification leased to {} (attempt {}; checks the result of {})", job.id(),
               v->task_id, Who(worker), attempt, Who(original));
  activity_.TaskEvent(job.id(), "verifying", v->task_id, attempt, worker,
                      "renders the task again to check the result of " + original + " (" + v->reason + ")");
  Lease lease;
  lease.lease_id = v->lease_id;
  lease.worker_id = worker;
  lease.job_id = job.id();
  lease.task_id = v->task_id;
  lease.attempt = attempt;
  lease.lease_seconds = options_.lease_seconds;
  lease.task = job.task(v->task_id);
  lease.config = job.shared_config();
  return lease;
}

CompleteResult Scheduler::CompleteVerification(const std::string& lease_id, const std::string& worker_id,
                                               std::span<const float> rgb_sums, RadiancePart part) {
  Effects fx;
  CompleteResult result;
  // 1. Claim, as for a task: the lease must be live and the caller's; pinned while it is compared.
  uint64_t id = 0;
  TaskSpec task;
  std::shared_ptr<const JobConfig> config;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    HeardLocked(worker_id, now);
    Verification* v = verification_.FindLease(lease_id);
    if (v && now >= v->deadline && !v->checking) {
      ExpireVerificationLocked(*v, now, fx);
      v = nullptr;
    }
    if (v && v->verifier != worker_id) {
      result.status = CompleteStatus::kNotHolder;
      result.reason = "the lease is held by another worker";
      NotTheHolderLocked(v->job->id(), v->task_id, worker_id, v->verifier, "CompleteTask", fx);
    } else if (!v || v->checking) {
      ++counters_.ignored;
      result.reason =
          v ? "a result for this lease is already being checked" : "unknown, expired or finished lease";
    } else {
      v->checking = true;
      id = v->id;
      task = v->job->task(v->task_id);
      config = v->config;
      result.job_id = v->job->id();
      result.task_id = v->task_id;
    }
  }
  if (id == 0) {
    Run(fx);
    return result;
  }
  // 2. Check and digest (no lock, O(pixels)). Not bounded: what counts is the digest.
  CheckedResult checked{std::nullopt, "", ResultCheck::Verdict::kOk};
  std::string digest;
  try {
    checked = ResultMerger::Check(task, config->camera.width, config->image_height(), rgb_sums);
    if (checked.valid && part != task.part)
      checked = CheckedResult{std::nullopt, "part: the result is not of the task's part",
                              ResultCheck::Verdict::kInvalid};
    if (checked.valid) digest = ResultMerger::Digest(rgb_sums);
  } catch (...) {
    std::lock_guard lock(mu_);
    if (Verification* v = verification_.Find(id)) v->checking = false;  // the lease stays live
    throw;
  }
  // 3. Compare (mu_): the same bytes, or the referee decides.
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    Verification* v = verification_.Find(id);
    if (!v || v->lease_id != lease_id) {
      ++counters_.ignored;  // the job restarted or ended meanwhile
      result.reason = "the job ended or restarted while the result was checked";
    } else {
      v->checking = false;
      Job& job = *v->job;
      const uint32_t attempt = job.runtime(v->task_id).attempts + v->leases;
      const std::string original = v->digests.front().first;
      if (!checked.valid) {
        ++counters_.rejected;
        result.status = CompleteStatus::kRejected;
        result.reason = checked.problem;
        activity_.TaskEvent(job.id(), "rejected", v->task_id, attempt, worker_id, checked.problem);
        VerificationAttemptFailedLocked(*v, "rejected result: " + checked.problem, now, fx);
      } else if (digest == v->digests.front().second) {
        result.status = CompleteStatus::kVerification;
        ++counters_.verified;
        verification_.CountVerified(job);
        spdlog::info("job {} task {}: verified: worker {} reproduced the result of {} bit for bit", job.id(),
                     v->task_id, Who(worker_id), Who(original));
        activity_.TaskEvent(job.id(), "verified", v->task_id, attempt, worker_id,
                            "reproduced the result of " + original + " bit for bit (" + v->reason + ")");
        verification_.Remove(id);
        Touch(job, fx);
        MaybeSucceed(job, now, fx);
      } else {
        result.status = CompleteStatus::kVerification;
        ++counters_.mismatches;
        spdlog::warn(
            "job {} task {}: MISMATCH: the result of worker {} differs from that of {}; the coordinator "
            "renders the task to decide",
            job.id(), v->task_id, Who(worker_id), Who(original));
        activity_.TaskEvent(job.id(), "mismatch", v->task_id, attempt, worker_id,
                            "differs from the result of " + original + "; the coordinator renders the task");
        v->digests.emplace_back(worker_id, digest);
        ToRefereeLocked(*v, fx);
        Touch(job, fx);
      }
    }
  }
  Run(fx);
  return result;
}

std::optional<ExtendResult> Scheduler::ExtendVerificationLocked(const std::string& lease_id,
                                                                const std::string& worker_id, double now,
                                                                Effects& fx) {
  Verification* v = verification_.FindLease(lease_id);
  if (!v) return std::nullopt;
  if (now >= v->deadline && !v->checking) {
    ExpireVerificationLocked(*v, now, fx);
    return ExtendResult{};
  }
  if (v->verifier != worker_id) {
    NotTheHolderLocked(v->job->id(), v->task_id, worker_id, v->verifier, "ExtendLease", fx);
    return ExtendResult{.not_holder = true};
  }
  v->deadline = now + options_.lease_seconds;
  return ExtendResult{true, options_.lease_seconds};
}

std::optional<FailOutcome> Scheduler::FailVerificationLocked(const std::string& lease_id,
                                                             const std::string& worker_id,
                                                             const std::string& reason, double now,
                                                             Effects& fx) {
  Verification* v = verification_.FindLease(lease_id);
  if (!v) return std::nullopt;
  if (now >= v->deadline && !v->checking) {
    ExpireVerificationLocked(*v, now, fx);
    return FailOutcome::kUnknownLease;
  }
  if (v->checking) return FailOutcome::kUnknownLease;  // its result decides
  if (v->verifier != worker_id) {
    NotTheHolderLocked(v->job->id(), v->task_id, worker_id, v->verifier, "FailTask", fx);
    return FailOutcome::kNotHolder;
  }
  // As a task's, with one difference: "not retryable" does not fail the job — another worker
  // already rendered this task, so it counts as a failed attempt of this worker only.
  activity_.TaskEvent(v->job->id(), "failed", v->task_id, v->job->runtime(v->task_id).attempts + v->leases,
                      worker_id, reason);
  VerificationAttemptFailedLocked(*v, "worker: " + reason, now, fx);
  return FailOutcome::kFailed;
}

bool Scheduler::ReturnVerificationLocked(const std::string& lease_id, Effects& fx) {
  Verification* v = verification_.FindLease(lease_id);
  if (!v) return false;
  if (v->checking) return true;
  ++counters_.returned;
  activity_.TaskEvent(v->job->id(), "returned", v->task_id, v->job->runtime(v->task_id).attempts + v->leases,
                      v->verifier, "the lease never reached the worker");
  verification_.Requeue(*v);
  Touch(*v->job, fx);
  return true;
}

void Scheduler::ExpireVerificationLocked(Verification& v, double now, Effects& fx) {
  ++counters_.expired;
  std::string detail;
  if (health_.LeaseRanOut(v.verifier, v.deadline - options_.lease_seconds, now)) {
    detail = "no call from the worker since the lease was renewed: marked lost";
    activity_.WorkerLost(v.verifier, true);
  }
  activity_.TaskEvent(v.job->id(), "expired", v.task_id, v.job->runtime(v.task_id).attempts + v.leases,
                      v.verifier, detail);
  VerificationAttemptFailedLocked(v, "lease expired (worker " + v.verifier + ")", now, fx);
}

void Scheduler::VerificationAttemptFailedLocked(Verification& v, const std::string& reason, double now,
                                                Effects& fx) {
  Job& job = *v.job;
  const std::string verifier = v.verifier;
  ++counters_.failed_attempts;
  CountFailure(job, verifier, v.task_id, job.runtime(v.task_id).attempts + v.leases, reason, now);
  if (!verifier.empty() && !FailedBefore(v, verifier)) v.failed_verifiers.push_back(verifier);
  Touch(job, fx);
  if (v.failed_verifiers.size() >= options_.max_attempts) {
    // As a task gives up after failures on max_attempts distinct workers: here the coordinator
    // renders it instead.
    v.no_verifier = true;
    spdlog::warn("job {} task {}: verification failed on {} workers (last: {}): the coordinator renders it",
                 job.id(), v.task_id, v.failed_verifiers.size(), reason);
    ToRefereeLocked(v, fx);
    return;
  }
  verification_.Requeue(v);
  ServeWaiters(fx);
}

void Scheduler::ToRefereeLocked(Verification& v, Effects& fx) {
  verification_.ToReferee(v);
  ++counters_.refereed;
  activity_.TaskEvent(v.job->id(), "refereed", v.task_id, 0, "",
                      v.no_verifier ? "no worker could verify it: the coordinator renders the task"
                                    : "the coordinator renders the task to decide");
  fx.referee.push_back(RefereeCase{v.id, v.job->id(), v.job->task(v.task_id), v.config});
}

void Scheduler::RefereeIfNoVerifierLocked(Job& job, double now, Effects& fx) {
  for (Verification* v : verification_.QueuedOf(job)) {
    const std::string& original = v->digests.front().first;
    const bool someone = health_.AnyLiveWorker(
        [&](const std::string& w) {
          return w != original && !FailedBefore(*v, w) && !health_.IsBlocklisted(job.id(), w);
        },
        now);
    if (someone) continue;
    v->no_verifier = true;
    spdlog::info("job {} task {}: no live worker but {} may verify it: the coordinator renders it", job.id(),
                 v->task_id, Who(original));
    ToRefereeLocked(*v, fx);
  }
}

void Scheduler::TickVerificationLocked(double now, Effects& fx) {
  for (const uint64_t id : verification_.Expired(now))
    if (Verification* v = verification_.Find(id)) ExpireVerificationLocked(*v, now, fx);
  if (!verification_.HasQueued()) return;
  // Workers are lost by silence here: a job with nothing but verifications left may have no
  // verifier any more.
  for (Job* job : jobs_.InSubmissionOrder())
    if (job->active() && verification_.Pending(*job) > 0 && job->count(TaskState::kQueued) == 0 &&
        job->count(TaskState::kLeased) == 0)
      RefereeIfNoVerifierLocked(*job, now, fx);
}

void Scheduler::SucceedOnTarget(Job& job, double now, Effects& fx) {
  if (verification_.Pending(job) == 0) {
    FinishJob(job, JobState::kSucceeded, "", now, fx);
    return;
  }
  // What the job's end would cancel goes now; it ends once its verifications are done.
  for (uint64_t id = 0; id < job.num_tasks(); ++id) {
    const TaskRuntime& rt = job.runtime(id);
    if (rt.state == TaskState::kQueued) {
      Dequeue(job, id);
      job.SetTaskState(id, TaskState::kCancelled);
    } else if (rt.state == TaskState::kLeased && !rt.merging) {
      leases_.Erase(rt.lease_id);
      activity_.TaskEvent(job.id(), "cancelled", id, rt.attempts, rt.worker_id, "the noise target was met");
      job.SetTaskState(id, TaskState::kCancelled);
    }
  }
  job.stopping = true;
  spdlog::info("job {}: noise target met; it succeeds once its {} pending verifications are done", job.id(),
               verification_.Pending(job));
  Touch(job, fx);
}

void Scheduler::RefereeVerdict(uint64_t verification_id, const std::string& digest,
                               const std::string& error) {
  Effects fx;
  std::vector<std::string> convict;
  std::string job_id, evidence;
  uint64_t task_id = 0;
  std::optional<uint32_t> epoch;  // of the checked result, if its author is convicted
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    Verification* v = verification_.Find(verification_id);
    if (!v || v->state != Verification::State::kRefereeing) return;
    Job& job = *v->job;
    const bool attached = !v->detached;
    const std::string original = v->digests.front().first;
    const std::string what = "task " + std::to_string(v->task_id);
    if (!error.empty()) {
      if (v->digests.size() == 1) {
        // No mismatch, only no verifier: the result stays merged, unverified.
        spdlog::warn(
            "job {} {}: the coordinator could not render it to verify the result of {} ({}): unverified",
            job.id(), what, Who(original), error);
        activity_.TaskEvent(job.id(), "unverified", v->task_id, 0, original,
                            "the coordinator could not render the task: " + error);
        verification_.Remove(verification_id);
        if (attached) MaybeSucceed(job, now, fx);
      } else {
        // Two workers disagree and nobody can tell which is right: the image cannot be trusted.
        const std::string why = what + ": the results of " + original + " and " + v->digests[1].first +
                                " differ, and the coordinator could not render the task to decide (" + error +
                                ")";
        activity_.TaskEvent(job.id(), "unverified", v->task_id, 0, "", why);
        verification_.Remove(verification_id);
        if (attached && job.active()) {
          FinishJob(job, JobState::kFailed, why, now, fx);
          spdlog::error("job {}: failed: {}", job.id(), why);
        }
      }
    } else {
      std::string agrees;
      for (const auto& [worker, d] : v->digests) {
        if (d != digest) {
          if (std::find(convict.begin(), convict.end(), worker) == convict.end()) convict.push_back(worker);
        } else if (agrees.empty()) {
          agrees = worker;
        }
      }
      if (convict.empty()) {
        ++counters_.verified;
        if (attached) verification_.CountVerified(job);
        activity_.TaskEvent(
            job.id(), "verified", v->task_id, 0, "",
            "the coordinator's render reproduces the result of " + original + " (" + v->reason + ")");
        verification_.Remove(verification_id);
        if (attached) MaybeSucceed(job, now, fx);
      } else {
        // Pending until the conviction removes it: the job must not succeed in between.
        job_id = job.id();
        task_id = v->task_id;
        // Only the author's result was merged: a lying verifier's never was (ConvictInJob).
        if (std::find(convict.begin(), convict.end(), original) != convict.end()) epoch = v->epoch;
        evidence = what + ": its result differs from the coordinator's render of it" +
                   (agrees.empty() ? "" : ", which " + agrees + "'s result reproduces");
        std::string names;
        for (const std::string& w : convict) names += (names.empty() ? "" : ", ") + w;
        spdlog::error("job {} {}: the coordinator's render {}: convicting {}", job.id(), what,
                      agrees.empty() ? "agrees with no worker" : "agrees with " + Who(agrees), names);
      }
    }
    Touch(job, fx);
  }
  Run(fx);
  if (!convict.empty()) Convict(job_id, convict, task_id, evidence, epoch, verification_id);
}

bool Scheduler::Convict(const std::string& job_id, const std::vector<std::string>& workers, uint64_t task_id,
                        const std::string& evidence, std::optional<uint32_t> result_epoch,
                        uint64_t verification_id) {
  std::shared_ptr<Job> job;  // shared: valid without the lock even if the job is deleted meanwhile
  MapTracingHook* hook = nullptr;
  {
    std::lock_guard lock(mu_);
    if (jobs_.Find(job_id)) job = jobs_.Shared(job_id);
    hook = map_hook_;
    if (!job && verification_id != 0) verification_.Remove(verification_id);
  }
  if (!job) return false;
  // Their pieces leave every stored map first, so that the restarted jobs wait for maps traced
  // again without them (map_tracing_hook.h).
  std::map<std::string, std::vector<std::string>> used_their_maps;  // job id → its convicted workers
  bool used_here = false;  // the job itself used a map with their pieces
  if (hook)
    for (const std::string& w : workers) {
      for (const std::string& id : hook->WorkerConvicted(w)) {
        if (id != job_id)
          used_their_maps[id].push_back(w);
        else
          used_here = true;
      }
    }
  const bool restarted =
      ConvictInJob(*job, workers, task_id, evidence, result_epoch, verification_id, used_here);
  for (const auto& [id, convicted] : used_their_maps) {
    std::shared_ptr<Job> other;
    {
      std::lock_guard lock(mu_);
      if (jobs_.Find(id)) other = jobs_.Shared(id);
    }
    if (other)
      ConvictInJob(*other, convicted, 0,
                   "its image used a photon map with pieces traced by a worker convicted in job " + job_id +
                       " (" + evidence + ")",
                   std::nullopt, 0, /*used_their_maps=*/true);
  }
  return restarted;
}

bool Scheduler::ConvictInJob(Job& job, const std::vector<std::string>& workers, uint64_t task_id,
                             const std::string& evidence, std::optional<uint32_t> result_epoch,
                             uint64_t verification_id, bool used_their_maps) {
  Effects fx;
  bool restarted = false;
  {
    std::lock_guard image(job.image_mu);  // the restart replaces the accumulator
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    if (verification_id != 0) verification_.Remove(verification_id);
    std::string names;
    for (const std::string& w : workers) {
      names += (names.empty() ? "" : ", ") + Who(w);
      CountFailure(job, w, task_id, 0, "convicted: " + evidence, now, /*convicted=*/true);
      activity_.TaskEvent(job.id(), "convicted", task_id, 0, w, evidence);
      // Stored in the job's row so that a restarted coordinator blocklists it again (recovery.cpp).
      if (std::find(job.convicted_workers.begin(), job.convicted_workers.end(), w) ==
          job.convicted_workers.end()) {
        job.convicted_workers.push_back(w);
        job.row_dirty = true;
      }
    }
    Touch(job, fx);
    // Whether the job's image may hold their work: their result merged in this epoch (an earlier
    // epoch's left with its restart), a map with their pieces, a merged task of theirs — or of a
    // worker no longer known (recovered tasks). An ended job (its tasks may be released) is left.
    bool holds_their_work =
        job.active() && ((result_epoch && *result_epoch == job.epoch()) || used_their_maps);
    for (uint64_t id = 0; job.active() && id < job.num_tasks() && !holds_their_work; ++id) {
      const TaskRuntime& rt = job.runtime(id);
      holds_their_work =
          rt.state == TaskState::kDone &&
          (rt.worker_id.empty() || std::find(workers.begin(), workers.end(), rt.worker_id) != workers.end());
    }
    if (!job.active()) {
      health_.JobEnded(job.id());  // the job's failure counts went with its end; so does this one's
      spdlog::error("job {}: worker {} convicted ({}) after the job ended: left as it is", job.id(), names,
                    evidence);
    } else if (!holds_their_work) {
      // Nothing of theirs is in the image (their results went with an earlier restart, or never
      // merged): blocklisted, their leases revoked, the job goes on.
      RevokeLeasesLocked(job, workers, "its worker was convicted", fx);
      spdlog::error(
          "job {}: worker {} convicted ({}): blocklisted for the job; none of its results is in the "
          "image, the job goes on",
          job.id(), names, evidence);
      MaybeSucceed(job, now, fx);
    } else {
      restarted = true;
      // Its leases, queued tasks and verifications go; the plan's tasks come back, all queued,
      // held until the empty image and the job's row are stored.
      for (uint64_t id = 0; id < job.num_tasks(); ++id) {
        const TaskRuntime& rt = job.runtime(id);
        if (rt.state == TaskState::kLeased) leases_.Erase(rt.lease_id);
        if (rt.state == TaskState::kQueued) Dequeue(job, id);
      }
      for (auto it = held_.begin(); it != held_.end();)
        it = it->first.first == job.id() ? held_.erase(it) : std::next(it);
      verification_.DropJob(job, /*ended=*/false);
      const uint64_t merged_before = job.count(TaskState::kDone);
      job.Restart(ScheduledTasks(job.config()), now);
      sources_[&job] = task_sources_(job.config());
      queue_.Hold(job);
      for (uint64_t id = 0; id < job.num_tasks(); ++id) Enqueue(job, id, fx);
      spdlog::error(
          "job {}: worker {} convicted of a wrong result ({}): blocklisted for the job; the job starts again "
          "from nothing without it ({} merged tasks dropped)",
          job.id(), names, evidence, merged_before);
      activity_.TaskEvent(job.id(), "restarted", task_id, 0, workers.front(),
                          "its image held results of a convicted worker: " + std::to_string(merged_before) +
                              " merged tasks dropped, every task queued again");
    }
  }
  Run(fx);
  return restarted;
}

void Scheduler::RevokeLeasesLocked(Job& job, const std::vector<std::string>& workers, const std::string& why,
                                   Effects& fx) {
  auto named = [&](const std::string& w) {
    return std::find(workers.begin(), workers.end(), w) != workers.end();
  };
  for (uint64_t id = 0; id < job.num_tasks(); ++id) {
    const TaskRuntime& rt = job.runtime(id);
    // A result being merged decides its attempt (TaskRuntime::merging).
    if (rt.state != TaskState::kLeased || rt.merging || !named(rt.worker_id)) continue;
    activity_.TaskEvent(job.id(), "revoked", id, rt.attempts, rt.worker_id, why);
    leases_.Erase(rt.lease_id);
    if (job.stopping && job.task(id).part != RadiancePart::kUnmapped) {
      job.SetTaskState(id, TaskState::kCancelled);  // past its time budget: not run again (CheckTimeBudget)
      MaybeSucceed(job, clock_.Now(), fx);
      continue;
    }
    job.SetTaskState(id, TaskState::kQueued);
    Enqueue(job, id, fx);
  }
  for (const std::string& w : workers)
    for (Verification* v : verification_.LeasedTo(job, w)) {
      activity_.TaskEvent(job.id(), "revoked", v->task_id, job.runtime(v->task_id).attempts + v->leases, w,
                          why);
      v->failed_verifiers.push_back(w);  // never leased to it again
      verification_.Requeue(*v);
    }
  Touch(job, fx);
  ServeWaiters(fx);
}

void Scheduler::BlocklistForHijack(const std::string& job_id, const std::string& worker_id, uint64_t task_id,
                                   const std::string& evidence) {
  Effects fx;
  {
    std::lock_guard lock(mu_);
    Job* job = jobs_.Find(job_id);
    if (!job || !job->active()) return;
    if (health_.Blocklist(job_id, worker_id, "presented another worker's lease: " + evidence, clock_.Now())) {
      activity_.TaskEvent(job_id, "convicted", task_id, 0, worker_id, evidence);
      activity_.WorkerBlocklisted(worker_id, job_id);
      spdlog::error(
          "job {}: worker {} blocklisted for the job: {} (no restart: nothing about a result is proven)",
          job_id, Who(worker_id), evidence);
    }
    // Stored with the job, boundedly: each name costs the caller one call with a lease of its own,
    // and the row and checkpoint carry the list.
    if (std::find(job->convicted_workers.begin(), job->convicted_workers.end(), worker_id) ==
            job->convicted_workers.end() &&
        job->convicted_workers.size() < kMaxConvictedWorkersPerJob) {
      job->convicted_workers.push_back(worker_id);
      job->row_dirty = true;
    }
    RevokeLeasesLocked(*job, {worker_id}, "its worker presented another worker's lease", fx);
  }
  Run(fx);
}

}  // namespace pf::server
