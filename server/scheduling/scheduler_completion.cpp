// Scheduler, part: a result handed in — the one check, the merge, failed attempts
// (scheduler.h, "Workers"; docs/farm.md, "Durability" D1).
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <utility>

#include "common/core/error.h"
#include "proto/limits.h"
#include "server/scheduling/scheduler.h"
#include "server/scheduling/stop_rules.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

CompleteResult Scheduler::Complete(const std::string& lease_id, const std::string& worker_id,
                                   std::span<const float> rgb_sums, RadiancePart part) {
  const bool verify = verification_.enabled();
  if (verify && IsVerificationLease(lease_id))
    return CompleteVerification(lease_id, worker_id, rgb_sums, part);
  Effects fx;
  CompleteResult result;
  // 1. Claim (global lock, O(1)): the lease must be live; it is pinned (TaskRuntime::merging) so
  //    that it neither expires nor takes a second result while this one is checked.
  Job* job = nullptr;
  std::shared_ptr<Job> held;  // keeps the job valid until the result is decided (RemoveJob)
  uint64_t task_id = 0;
  TaskSpec task;                   // a copy: the job's task vector may grow (AppendTasks) meanwhile
  bool needs_accumulator = false;  // read under the lock: the pointer changes under both locks
  std::vector<double> references;  // verification: the outlier test's (result_verification.h)
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    HeardLocked(worker_id, now);
    LeaseTable::Entry* ref = FindLiveLease(lease_id, now, fx);
    if (ref && ref->kind != LeaseKind::kRenderTask) ref = nullptr;  // a piece delivers an upload, not this
    if (ref && ref->job->runtime(ref->task_id).worker_id != worker_id) {
      // Another worker's result for this lease is not the holder's: nothing is merged, and the
      // holder's lease stays as it is.
      result.status = CompleteStatus::kNotHolder;
      result.reason = "the lease is held by another worker";
      NotTheHolderLocked(ref->job->id(), ref->task_id, worker_id, ref->job->runtime(ref->task_id).worker_id,
                         "CompleteTask", fx);
    } else if (!ref || ref->job->runtime(ref->task_id).merging) {
      ++counters_.ignored;
      result.reason =
          ref ? "a result for this lease is already being merged" : "unknown, expired or finished lease";
      spdlog::info("result for lease {} ignored: {}", limits::Quote(lease_id, limits::kMaxIdBytes),
                   result.reason);
    } else {
      job = ref->job;
      held = jobs_.Shared(job->id());
      task_id = ref->task_id;
      task = job->task(task_id);
      job->runtime(task_id).merging = true;
      needs_accumulator = !job->accumulator_if_loaded();
      if (verify && verification_.options().outliers)
        references = verification_.References(*job, ResultGroup(task));
    }
  }
  if (!job) {
    Run(fx);
    return result;
  }
  result.job_id = job->id();
  result.task_id = task_id;
  // Until the commit, an exception (an allocation failing in the check, a hook in a test) must
  // not leave the lease pinned: unpinned, it expires or takes a result again as any lease would.
  struct Unpin {
    Scheduler* self;
    Job* job;
    uint64_t task_id;
    std::string lease_id;
    bool armed = true;
    ~Unpin() {
      if (!armed) return;
      {
        std::lock_guard lock(self->mu_);
        if (job->has_runtime(task_id) && job->runtime(task_id).lease_id == lease_id)
          job->runtime(task_id).merging = false;  // as the commit does
      }
      try {  // a destructor must not throw, even if logging cannot allocate
        spdlog::error(
            "job {} task {}: the result for lease {} could not be checked (exception); the lease "
            "stays live",
            job->id(), task_id, limits::Quote(lease_id, limits::kMaxIdBytes));
      } catch (...) {
      }
    }
  } unpin{this, job, task_id, lease_id};

  // 2. Check (no lock, O(pixels)): the one check of a worker's result (the edge), and the pixel
  //    indices the merge needs. The configuration is immutable.
  const JobConfig& config = job->config();
  const int width = config.camera.width, height = config.image_height();
  CheckedResult checked = ResultMerger::Check(task, width, height, rgb_sums, config.max_sample_radiance);
  if (part != task.part && checked.valid) {
    // Hierarchical plan with part indirect (radiance_part.h): a worker that does not know
    // Task.part renders everything, and its sums would count emission and direct light twice.
    const auto name = [](RadiancePart p) {
      return p == RadiancePart::kMapped ? "mapped" : p == RadiancePart::kUnmapped ? "unmapped" : "all";
    };
    checked = CheckedResult{std::nullopt,
                            std::string("part: the result is of part ") + name(part) + ", the task's is " +
                                name(task.part) + " (a worker older than Task.part? upgrade it)",
                            ResultCheck::Verdict::kInvalid};
  }
  std::string digest;  // of a result above the bound that is valid apart from the bound
  if (checked.verdict == ResultCheck::Verdict::kImplausible) {
    CheckedResult unbounded = ResultMerger::Check(task, width, height, rgb_sums);
    if (unbounded.valid) {
      digest = ResultMerger::Digest(rgb_sums);
      checked.valid = unbounded.valid;  // merged only once confirmed (below)
    } else {
      checked = std::move(unbounded);  // invalid anyway
    }
  }
  std::string problem = checked.problem;
  std::vector<uint32_t> pixels;
  if (checked.valid) {
    try {
      pixels = merger_.PixelsOfTask(task, width, height);
      const uint64_t image_pixels = uint64_t(width) * uint64_t(height);
      for (uint32_t p : pixels)  // checked here: after the commit, the add must not fail
        if (p >= image_pixels) throw InputError("pixels: index " + std::to_string(p) + " outside the image");
    } catch (const InputError& e) {
      problem = e.what();  // the task's own pixel set is out of range: a coordinator bug
      checked = CheckedResult{std::nullopt, problem, ResultCheck::Verdict::kInvalid};
    }
  }
  // Verification: chosen now, when the result arrives (the CSPRNG, or the outlier test); only a
  // chosen result's digest is computed.
  ResultSummary summary;
  std::string verify_reason;
  if (verify && checked.valid) {
    summary = SummarizeResult(task, rgb_sums);
    const OutlierScore score = ScoreAgainst(summary.midmean, references);
    if (verification_.options().outliers && score.outlier)
      verify_reason = "outlier: z = " + std::to_string(score.z);
    else if (verification_.ChooseAtRandom())
      verify_reason = "sampled";
    if (!verify_reason.empty() && digest.empty()) digest = ResultMerger::Digest(rgb_sums);
  }
  // The job's first merge allocates its accumulator (O(pixels)) here, before the commit: once a
  // task is recorded as merged nothing may fail, or its samples would be lost.
  std::unique_ptr<Accumulator> fresh;
  if (checked.valid && needs_accumulator)
    fresh = std::make_unique<Accumulator>(config.plan, width, height, config.settings.progressive_alpha);
  if (options_.probe) options_.probe->BeforeCommit(lease_id);
  unpin.armed = false;  // from here on the commit below unpins

  // 3. Commit (image_mu, then the global lock for O(1) bookkeeping), add (image_mu only,
  //    O(pixels)), then the rules that follow a merge. Commit and add happen within one hold of
  //    image_mu, so whoever holds it sees an accumulator that agrees with the job's merged tasks.
  std::unique_lock image(job->image_mu);
  bool merged = false;
  {
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    TaskRuntime gone;  // a restart took the task away (an appended task of a dynamic plan)
    TaskRuntime& rt = job->has_runtime(task_id) ? job->runtime(task_id) : gone;
    if (rt.lease_id == lease_id) rt.merging = false;  // not a new lease of a task a restart re-created
    const bool convicted = std::find(job->convicted_workers.begin(), job->convicted_workers.end(),
                                     worker_id) != job->convicted_workers.end();
    if (convicted && rt.state == TaskState::kLeased && rt.lease_id == lease_id) {
      // Convicted while this result was checked (its lease was pinned, so not revoked): never
      // merged; the task goes back to the queue.
      ++counters_.ignored;
      result.reason = "its worker was convicted while the result was checked";
      spdlog::info("job {} task {}: result ignored: {}", job->id(), task_id, result.reason);
      leases_.Erase(lease_id);
      job->SetTaskState(task_id, TaskState::kQueued);
      Enqueue(*job, task_id, fx);
    } else if (rt.state != TaskState::kLeased || rt.lease_id != lease_id) {
      // Only a job's end (cancel, failure, stop rule) or its restart (ConvictWorker) takes a
      // pinned lease away.
      ++counters_.ignored;
      result.reason = "the job ended while the result was checked";
      spdlog::info("job {} task {}: result ignored: {}", job->id(), task_id, result.reason);
    } else {
      if (checked.verdict == ResultCheck::Verdict::kImplausible) {
        // Merged (valid without the bound) once a second worker's bytes are identical.
        problem = ConfirmImplausible(*job, task_id, digest, ResultCheck{checked.verdict, checked.problem});
      }
      if (!problem.empty()) {
        ++counters_.rejected;
        result.status = CompleteStatus::kRejected;
        result.reason = problem;
        spdlog::warn("job {} task {}: result of attempt {} rejected: {}", job->id(), task_id, rt.attempts,
                     problem);
        activity_.TaskEvent(job->id(), "rejected", task_id, rt.attempts, rt.worker_id, problem);
        FailAttempt(*job, task_id, "rejected result: " + problem, true, now, fx);
      } else {
        ++counters_.merged;
        leases_.Erase(lease_id);
        job->RecordMerge(task_id);
        job->eta.RecordCompletion(now, double(job->task_work(task_id)));
        result.status = CompleteStatus::kMerged;
        result.merge_seq = job->merge_seq();
        result.epoch = job->epoch();
        result.worker_id = rt.worker_id;
        activity_.TaskEvent(job->id(), "merged", task_id, rt.attempts, result.worker_id);
        spdlog::info("job {} task {}: merged (attempt {}, worker {}; {}/{} done)", job->id(), task_id,
                     rt.attempts, rt.worker_id, job->count(TaskState::kDone), job->num_tasks());
        Touch(*job, fx);
        merged = true;
        if (verify) {
          verification_.RecordMean(*job, summary.group, summary.midmean);
          if (!verify_reason.empty())
            AddVerificationLocked(*job, task_id, result.worker_id, digest, verify_reason, fx);
        }
      }
    }
  }
  if (merged) {
    if (!job->accumulator_if_loaded()) {
      // Allocated before the commit (above); the pointer changes under both locks. A concurrent
      // first merge may have installed one meanwhile: then ours is dropped. The fallback covers a
      // claim that saw one loaded (it is released only for finished jobs, whose results the
      // commit refuses).
      if (!fresh)
        fresh = std::make_unique<Accumulator>(config.plan, width, height,
                                              config.settings.progressive_alpha);  // not reached
      std::lock_guard lock(mu_);
      job->set_accumulator(std::move(fresh));
    }
    Accumulator& acc = job->accumulator();
    ResultMerger::Merge(*checked.valid, pixels, acc);
    bool noise_due = false;
    {
      std::lock_guard lock(mu_);
      job->samples_merged = acc.samples_merged();
      noise_due = NoiseTargetDue(*job, clock_.Now(), options_.noise_check_interval);
    }
    const ErrorEstimates estimates =
        noise_due ? acc.Estimates() : ErrorEstimates{};  // O(pixels), off the lock
    std::lock_guard lock(mu_);
    const double now = clock_.Now();
    if (noise_due && job->active()) {
      job->noise_target_checked_at = now;
      job->SetNoise(estimates, now);
      if (NoiseTargetMet(*job)) {
        spdlog::info("job {}: {} after {} tasks: done", job->id(),
                     DescribeTargets(config.stop.targets(), job->estimates_cache),
                     job->count(TaskState::kDone));
        SucceedOnTarget(*job, now, fx);
      }
    }
    AddTasksFromSource(*job, fx);
    MaybeSucceed(*job, now, fx);
    ServeWaiters(fx);
  }
  image.unlock();
  Run(fx);
  return result;
}

std::string Scheduler::ConfirmImplausible(Job& job, uint64_t task_id, const std::string& digest,
                                          const ResultCheck& check) {
  // Above the bound is not proof of a fault (estimator tails are unbounded, docs/security.md
  // "Results"), and a rejection of an honest result would repeat on every retry (rendering is
  // deterministic) until the job fails. So: not merged, re-run; merged when a different worker
  // delivers the same bytes.
  TaskRuntime& rt = job.runtime(task_id);
  if (!rt.implausible_digest.empty() && digest == rt.implausible_digest &&
      rt.worker_id != rt.implausible_worker) {
    spdlog::warn(
        "job {} task {}: result above the bound reproduced bit for bit by worker {} (first from {}): merged "
        "({})",
        job.id(), task_id, rt.worker_id, rt.implausible_worker, check.reason);
    activity_.TaskEvent(job.id(), "confirmed", task_id, rt.attempts, rt.worker_id,
                        "reproduced a result above the bound first sent by " + rt.implausible_worker);
    return "";
  }
  rt.implausible_digest = digest;
  rt.implausible_worker = rt.worker_id;
  return check.reason + "; re-run, merged only if another worker reproduces it exactly";
}

void Scheduler::FailAttempt(Job& job, uint64_t task_id, const std::string& reason, bool retryable, double now,
                            Effects& fx) {
  TaskRuntime& rt = job.runtime(task_id);
  leases_.Erase(rt.lease_id);
  ++rt.failures;
  ++counters_.failed_attempts;
  rt.last_error = reason;
  const uint32_t attempt = rt.attempts;
  const std::string worker = rt.worker_id;
  if (worker.empty())
    ++rt.unattributed_failures;
  else if (std::find(rt.failed_workers.begin(), rt.failed_workers.end(), worker) == rt.failed_workers.end())
    rt.failed_workers.push_back(worker);
  Touch(job, fx);
  if (!job.active()) return;
  const bool blocklisted = CountFailure(job, worker, task_id, attempt, reason, now);
  if (job.stopping && job.task(task_id).part != RadiancePart::kUnmapped) {  // see CheckTimeBudget
    job.SetTaskState(task_id, TaskState::kCancelled);
    spdlog::info("job {} task {}: attempt {} ended ({}); not retried (time budget reached)", job.id(),
                 task_id, attempt, reason);
    MaybeSucceed(job, now, fx);
    return;
  }
  // A task fails its job on failures on max_attempts distinct workers, not on max_attempts
  // failures: one bad worker must not use up the attempts while good workers are busy. What bounds
  // the retries of a task every worker fails is the blocklist: each worker fails it at most
  // blocklist_failures times, then, with no worker left, the job fails.
  const std::string failed =
      "task " + std::to_string(task_id) + " attempt " + std::to_string(attempt) + " failed: " + reason;
  const uint32_t distinct = uint32_t(rt.failed_workers.size()) + rt.unattributed_failures;
  std::string why;
  if (!retryable) {
    why = failed + " (not retryable)";
  } else if (distinct >= options_.max_attempts) {
    std::string names;
    for (const std::string& w : rt.failed_workers) names += (names.empty() ? "" : ", ") + w;
    why = failed + "; gave up after " + std::to_string(rt.failures) + " failed attempts on " +
          std::to_string(distinct) + " workers (" + names +
          (rt.unattributed_failures ? (names.empty() ? "" : "; ") + std::to_string(rt.unattributed_failures) +
                                          " not attributed to a worker"
                                    : "") +
          ")";
  } else if (blocklisted) {
    if (const std::string none = NoWorkerLeft(job); !none.empty())
      why = failed + "; gave up after " + std::to_string(rt.failures) + " failed attempts: " + none;
  }
  if (!why.empty()) {
    job.SetTaskState(task_id, TaskState::kCancelled);
    FinishJob(job, JobState::kFailed, why, now, fx);
    spdlog::error("job {}: failed: {}", job.id(), why);
    return;
  }
  job.SetTaskState(task_id, TaskState::kQueued);
  Enqueue(job, task_id, fx);
  spdlog::warn("job {} task {}: attempt {} failed ({}); re-queued (failed on {} of {} workers)", job.id(),
               task_id, attempt, reason, distinct, options_.max_attempts);
  ServeWaiters(fx);
}

}  // namespace pf::server
