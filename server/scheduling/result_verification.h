#pragma once
// Result verification for a Scheduler (server/scheduling/scheduler.h; docs/farm.md "Result
// verification"): which merged results another worker renders a second time, compared bit for bit
// with the first, and what happens when they differ. Rendering is deterministic (docs/design.md,
// G1): an honest second render of a task is the same bytes on any worker, and on the coordinator.
//
//   chosen      when a result is merged: by the CSPRNG with probability `fraction`, decided when
//               the result arrives (so a worker cannot know whether its result will be checked),
//               or always when the outlier test flags it (ScoreAgainst below). Only a chosen
//               result's digest (ResultMerger::Digest) is computed.
//   leased      to a worker that is not the one whose result it checks, not blocklisted for the
//               job and that has not failed this verification before — as an ordinary task lease:
//               the same Task, the same lease id form, so that the worker cannot tell either. Its
//               lease expires, fails and returns like a task lease and counts in worker health.
//               Its result is never merged (CompleteTaskResponse.merged = false).
//   compared    the same digest: verified. Another: a mismatch, and the coordinator is the
//               referee (RefereeHook: it renders the task itself, off every lock); every worker
//               whose digest differs from the referee's is convicted (Scheduler::ConvictWorker).
//   no verifier after failed attempts on max_attempts distinct verifiers, or once the job has
//               nothing else left and no live worker may verify it, the referee renders it and
//               compares with the original.
//
// A job does not succeed while a verification of it is pending. A job's restart (a conviction) or
// its end drops its queued and leased verifications (their results are gone from its image); a
// referee already at work still convicts. In memory only, like worker health: a restarted
// coordinator forgets pending verifications (their results stay merged, unverified). Not
// thread-safe: the Scheduler's lock guards it.

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "common/plan/task_plan.h"

namespace pf::server {

class Job;
struct JobConfig;

// The outlier test's threshold and floor (docs/farm.md "Result verification": measured on real
// renders by bench/result_verification_bench.cpp). A result is an outlier when its statistic (the
// mid-mean, ResultSummary) lies more than kOutlierThreshold robust standard deviations (1.4826 ×
// the median absolute deviation) from the median of the other results of its pixel group, the
// deviation being at least kOutlierThreshold × kOutlierRelativeFloor × that median.
inline constexpr double kOutlierThreshold = 6.0;
inline constexpr double kOutlierRelativeFloor = 0.05;
// Results of a group kept for the test (the newest): the median of up to 63 others.
inline constexpr size_t kOutlierReferences = 63;
// Others needed before a result is tested.
inline constexpr size_t kOutlierMinReferences = 3;

struct VerificationOptions {
  double fraction = 0;    // of merged results, chosen by the CSPRNG (0 = none at random)
  bool outliers = false;  // verify every merged result the outlier test flags
};

// What the outlier test knows of a result: the group of results it is compared with — the same
// tile (over maps, rounds, samples), or for skipping every task of the job (each is a uniformly
// random subset of the image's pixels of the same size) — and statistics of its pixels' r + g + b
// per sample. The test uses the mid-mean (the mean of the middle half of the pixels' values): a
// random subset's mean swings with the few emitter pixels it happens to hold (an honest skipping
// result was 12 MADs out), its median is noisier than the mid-mean (bench: 92 % of x1.5 caught
// against 97 %). Scaling every value by f scales each statistic by f.
struct ResultSummary {
  uint64_t group = 0;
  double mean = 0;
  double median = 0;
  double midmean = 0;
};
ResultSummary SummarizeResult(const TaskSpec& task, std::span<const float> rgb_sums);
// The group alone (O(1)); kUntestedGroup for a list of pixels (a localization task's own).
inline constexpr uint64_t kUntestedGroup = 0;
uint64_t ResultGroup(const TaskSpec& task);

struct OutlierScore {
  bool tested = false;  // enough other results of the group
  double z = 0;         // |mean − median| / max(1.4826 · MAD, relative floor · |median|)
  bool outlier = false;
};
OutlierScore ScoreAgainst(double mean, std::span<const double> others, double threshold = kOutlierThreshold);

class ResultVerification {
 public:
  struct Verification {
    uint64_t id = 0;
    Job* job = nullptr;
    uint64_t task_id = 0;
    uint32_t epoch = 0;  // the job's epoch when the checked result was merged
    std::string reason;  // why it was chosen ("sampled", "outlier: z = …")
    std::shared_ptr<const JobConfig> config;
    // (worker, digest): [0] the result being checked, then every verifier whose digest differed.
    std::vector<std::pair<std::string, std::string>> digests;
    enum class State { kQueued, kLeased, kRefereeing } state = State::kQueued;
    std::string lease_id, verifier;
    double deadline = 0;
    uint32_t leases = 0;    // leases handed out (the lease's attempt continues the task's numbering)
    bool checking = false;  // a verifier's result is being compared (as TaskRuntime::merging)
    std::vector<std::string> failed_verifiers;
    // The referee renders it because no worker could, not because of a mismatch.
    bool no_verifier = false;
    // Its job restarted or ended: it keeps nothing from succeeding; a referee's verdict convicts.
    bool detached = false;
  };

  explicit ResultVerification(VerificationOptions options);
  const VerificationOptions& options() const { return options_; }
  bool enabled() const { return options_.fraction > 0 || options_.outliers; }

  // The CSPRNG's draw against `fraction` (tests may set the source: SetRandomForTest).
  bool ChooseAtRandom();
  void SetRandomForTest(std::function<double()> uniform) { uniform_ = std::move(uniform); }

  // Outlier references: the means of the group's merged results in the job (newest last).
  std::vector<double> References(const Job& job, uint64_t group) const;
  void RecordMean(const Job& job, uint64_t group, double mean);

  Verification& Add(Job& job, uint64_t task_id, std::string worker, std::string digest, std::string reason);
  Verification* Find(uint64_t id);
  Verification* FindLease(const std::string& lease_id);
  bool HasQueued() const { return queued_ > 0; }
  // The oldest queued verification `may_take` accepts; null if none.
  Verification* NextQueued(const std::function<bool(const Verification&)>& may_take);
  void Leased(Verification& v, std::string lease_id, std::string worker, double deadline);
  // Back to the queue (lease ended, failed or returned), or to the referee.
  void Requeue(Verification& v);
  void ToReferee(Verification& v);
  void Remove(uint64_t id);
  // Ids of leased verifications whose deadline is ≤ now (and no result is being compared).
  std::vector<uint64_t> Expired(double now) const;
  // Queued verifications of the job, oldest first.
  std::vector<Verification*> QueuedOf(const Job& job);
  // The job's verifications leased to `worker` whose result is not being compared.
  std::vector<Verification*> LeasedTo(const Job& job, const std::string& worker);

  // Pending (queued, leased or with the referee) verifications of the job, not detached.
  uint64_t Pending(const Job& job) const;
  uint64_t Verified(const Job& job) const;
  void CountVerified(const Job& job);
  // The job restarted (its results are gone: its references and counts too) or ended: its queued
  // and leased verifications are dropped, those with the referee detached.
  void DropJob(const Job& job, bool ended);
  // Whether a verification (a detached one with the referee included) still names the job.
  bool Names(const Job& job) const;
  // A deleted job (pf delete; after DropJob, and only if !Names): its counts go.
  void ForgetJob(const Job& job) { jobs_.erase(&job); }

 private:
  struct JobState {
    std::unordered_map<uint64_t, std::vector<double>> references;  // by group, ≤ kOutlierReferences
    uint64_t pending = 0, verified = 0;
  };
  void Unindex(Verification& v);

  VerificationOptions options_;
  std::function<double()> uniform_;
  uint64_t next_id_ = 1;
  std::map<uint64_t, std::unique_ptr<Verification>> all_;  // by id: oldest first
  std::unordered_map<std::string, uint64_t> by_lease_;
  uint64_t queued_ = 0;
  std::unordered_map<const Job*, JobState> jobs_;
};

}  // namespace pf::server
