#pragma once
// THE scheduler: which task a worker gets, how long it may keep it, what happens when it does
// not come back, and when a job is over. Owns every Job (server/jobs/) and merges results into
// their accumulators (server/assembly/). gRPC-free and clock-injected, so every rule below is
// unit-tested with a FakeClock and no sleeping (tests/server/scheduler_test.cpp).
//
// This class is the facade and the one lock; the rules live in pieces beside it:
//   task_source.h  where a job's tasks come from: all at submission (static plans), or created
//                  from the merged results (dynamic plans), asked after every merge
//   task_queue.h   the one queue, of render tasks and map pieces: pieces first (oldest map
//                  first), then tasks by priority, submission order and map affinity
//   lease_table.h  lease id → what it names (a render task, or a map piece: its kind); which ran
//                  out. One path (FindLiveLease) for Extend, Fail, ReturnLease, Complete, piece
//                  uploads and expiry, dispatching by the entry's kind
//   stop_rules.h   max rounds, time budget, target noise
//   worker_health.h  blocklists per job, quarantine, lost workers: who may get which work
//   farm_activity.h  workers and task events, for people
//
// Leases. A lease lasts lease_seconds; ExtendLease (heartbeat) renews it to now + lease_seconds.
// A lease belongs to the worker it was leased to: Extend, Complete and Fail name the caller's
// worker id, and another worker's call changes nothing (kNotHolder; docs/security.md). A lease
// that runs out (checked on every Tick and whenever the lease is used) ends the attempt: the task
// goes back to the queue and its next lease is attempt + 1. So does FailTask(retryable) and a
// rejected result (wrong size, NaN/Inf).
//
// Attempts and worker health (worker_health.h, docs/farm.md "Worker health"). A failed attempt
// counts against its worker: after blocklist_failures of them in one job the worker gets no more
// of that job's work (tasks and map pieces), and a worker blocklisted by quarantine_jobs jobs in
// quarantine_seconds gets nothing for quarantine_seconds. A task fails its job only after failed
// attempts on max_attempts *distinct* workers, or when no live worker is left that is not
// blocklisted for the job (so a one-worker farm still fails a broken job after blocklist_failures
// attempts), or on one FailTask(retryable = false); the job FAILS with the reason and its other
// tasks are cancelled. A retry goes to another waiting worker before the one that failed it. A
// lease handed to a long poll whose caller is already gone is returned without counting a
// failure (ReturnLease).
//
// Results. Only the current lease of a task can deliver its result; a task is merged at most
// once. A result for an unknown, expired, replaced or already-merged lease is answered
// kIgnored (CompleteTaskResponse.merged = false), never merged twice. One merge path: Complete
// checks a result once (ResultMerger::Check), merges the checked result, records it in the job,
// then asks the job's task source for new tasks, then applies the stop rules.
//
// Locks. One global lock (mu_) guards the queue, the leases and every job's bookkeeping; it is held
// only for O(1)/O(tasks) work. The O(pixels) work — checking a result's floats, merging it into
// the accumulator, resolving an image snapshot, serialising a checkpoint, the noise estimate — runs
// under the job's own image_mu (Job::image_mu), so results for different jobs merge in parallel
// and leases, heartbeats and status calls never wait for a merge. Order: image_mu, then mu_;
// never image_mu while holding mu_. Complete in three steps:
//   1. claim (mu_): the lease must be live; it is pinned (TaskRuntime::merging): it does not
//      expire, cannot be failed or returned, and another result for it is ignored;
//   2. check (no lock): ResultMerger::Check, the digest of a result above the bound, the pixels;
//   3. commit (image_mu, then mu_ briefly): if the job ended meanwhile the result is ignored (a
//      cancelled job's late result is dropped), if it is invalid the attempt fails, else the task
//      is DONE; then the add into the accumulator (image_mu only) and the rules that follow a
//      merge (mu_ again). Commit and add lie within one hold of image_mu, so a holder of image_mu
//      sees an accumulator that agrees with the job's merged tasks (checkpoints rely on it).
// A result is decided exactly once: by its claim (ignored) or by its commit.
//
// Long polls. LeaseOrWait answers at once if a task or a map piece is queued, else parks the
// caller until one is (submit, re-queue, a task source adding tasks, a map update) or its wait
// expires (Tick) — no busy waiting; callbacks always run outside the lock, exactly once per waiter.
//
// Verification (result_verification.h; docs/farm.md "Result verification"): a fraction of merged
// results, chosen by the CSPRNG when they arrive, and every result the outlier test flags, are
// rendered again by another worker under an ordinary task lease and compared bit for bit; a
// mismatch goes to the referee (referee_hook.h: the coordinator renders the task), and every
// worker whose digest differs from the referee's is convicted (ConvictWorker). A job does not
// succeed while a verification of it is pending. The lease, result and referee steps live in
// scheduler_verification.cpp; the hooks here are one call each.
//
// Hooks: the change listener hears the id of every job that changed (WatchJob), the persist
// listener that there is something to write (server/store/persister.h).

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <set>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "photonfarm/v1/farm.pb.h"
#include "server/assembly/image_snapshot.h"
#include "server/assembly/result_merger.h"
#include "server/clock.h"
#include "server/jobs/job.h"
#include "server/jobs/job_registry.h"
#include "server/scheduling/completion_probe.h"
#include "server/scheduling/farm_activity.h"
#include "server/scheduling/lease_table.h"
#include "server/scheduling/map_tracing_hook.h"
#include "server/scheduling/referee_hook.h"
#include "server/scheduling/result_verification.h"
#include "server/scheduling/task_queue.h"
#include "server/scheduling/task_source.h"
#include "server/scheduling/worker_health.h"
#include "server/store/persist_source.h"
#include "server/store/records.h"

namespace pf::server {

// How often a running job's elapsed time is written to the job table (Scheduler::Tick).
inline constexpr double kElapsedPersistSeconds = 1.0;

struct SchedulerOptions {
  double lease_seconds = 30;
  uint32_t max_attempts = 3;  // distinct workers a task may fail on before its job fails
  // Worker health (worker_health.h); a worker is lost after 2 × lease_seconds of silence.
  uint32_t blocklist_failures = 3;  // failed attempts in one job that blocklist a worker for it
  uint32_t quarantine_jobs = 3;     // blocklisted by this many jobs within quarantine_seconds: quarantined
  double quarantine_seconds = 900;
  double noise_check_interval = 0.5;  // seconds between noise estimates of one job
  // Result verification (result_verification.h): off unless set (pf-coordinator sets its flags).
  VerificationOptions verification = {};
  // Stamped into every job's stored spec (JobSpec.plan.build): the coordinator's PF_VERSION.
  std::string build = {};
  // Tests only (completion_probe.h); must outlive the scheduler. None in production.
  CompletionProbe* probe = nullptr;
};

struct LeaseRequest {
  std::string worker_id;
  std::vector<uint64_t> cached_map_seeds;
};

struct Lease {
  std::string lease_id;
  std::string worker_id;  // the holder (LeaseRequest.worker_id)
  std::string job_id;
  uint64_t task_id = 0;
  uint32_t attempt = 0;
  double lease_seconds = 0;
  TaskSpec task;
  std::shared_ptr<const JobConfig> config;
  std::optional<TraceChunkLease> chunk;  // a piece of a map to trace, not a render task (map_tracing_hook.h)
};

enum class FailOutcome { kFailed, kUnknownLease, kNotHolder };

struct ExtendResult {
  bool ok = false;
  double lease_seconds = 0;
  bool not_holder = false;  // the lease is live but another worker's: nothing changed
};

// kVerification: the result of a verification lease, compared and never merged (the worker is
// answered merged = false, as for an ignored result).
enum class CompleteStatus { kMerged, kIgnored, kRejected, kNotHolder, kVerification };
struct CompleteResult {
  CompleteStatus status = CompleteStatus::kIgnored;
  std::string reason;  // why ignored / rejected
  std::string job_id;
  uint64_t task_id = 0;
  uint64_t merge_seq = 0;  // kMerged: the job's merge count including this one
  uint32_t epoch = 0;      // kMerged: the job's restart count when it was merged (Job::epoch)
  std::string worker_id;   // kMerged: the worker that delivered it
};

// A consistent view of a job for clients: its status and (optionally) its merged image.
struct JobSnapshot {
  photonfarm::v1::JobStatus status;
  std::shared_ptr<const JobConfig> config;  // the validated job: what its image is of
  std::optional<ResolvedImage> image;       // if requested and the accumulator is in memory
  std::string checkpoint_path;              // else: read the image from here (finished, reloaded jobs)
  CheckpointSeal checkpoint_seal;           // … and only if the file carries this seal
};

// What the queued and running jobs hold, for the coordinator's budgets (server/rpc/budgets.h).
// A job's tasks and pixels count until its task list is released, i.e. while they are in memory
// (docs/farm.md "Coordinator memory": the persister's next flush after the job ended).
struct ActiveLoad {
  uint64_t jobs = 0;         // queued + running
  uint64_t tasks = 0;        // their tasks, as counted when they were added
  uint64_t pixels = 0;       // their images' pixels (width × height)
  uint64_t client_jobs = 0;  // of the queued and running jobs, the ones the client asked about submitted
};

struct SchedulerCounters {
  uint64_t leases = 0, merged = 0, ignored = 0, rejected = 0, expired = 0, failed_attempts = 0, returned = 0;
  // Result verification: leases of verifications, results verified (a second render or the
  // referee agreed), mismatches (sent to the referee), renders by the referee.
  uint64_t verification_leases = 0, verified = 0, mismatches = 0, refereed = 0;
  uint64_t lease_attempts = 0;  // searches of the queue for a task (a spinning poll would inflate it)
  uint64_t parked_polls = 0;    // long polls waiting right now
  // Tasks whose spec and runtime are in memory: those of active jobs and of finished jobs not
  // yet released (Job::ReleaseTasks; docs/farm.md "Coordinator memory").
  uint64_t tasks_in_memory = 0;
};

class Scheduler final : public PersistSource {
 public:
  using LeaseCallback = std::function<void(std::optional<Lease>)>;

  // `task_sources` makes each job's TaskSource (task_source.h) when the job is added.
  Scheduler(const Clock& clock, SchedulerOptions options, TaskSourceFactory task_sources = MakeTaskSource);
  ~Scheduler() override;
  Scheduler(const Scheduler&) = delete;
  Scheduler& operator=(const Scheduler&) = delete;

  // Set before use; called outside the lock.
  void SetChangeListener(std::function<void(const std::string& job_id)> listener);
  void SetPersistListener(std::function<void()> listener);

  // --- Jobs ---
  // A new job with a fresh id and its scheduled tasks; not yet visible (store it, then AddJob).
  std::unique_ptr<Job> PrepareJob(JobConfig config);
  // Makes a job visible and queues its QUEUED tasks (new jobs and jobs restored by recovery).
  void AddJob(std::unique_ptr<Job> job);
  // Recovery: later job ids are numbered above `seq`.
  void ReserveJobSeq(uint64_t seq);
  photonfarm::v1::JobStatus Status(const std::string& job_id);  // NotFoundError if unknown
  std::vector<photonfarm::v1::JobStatus> List(bool include_finished);
  // Up to `limit` jobs submitted after the job numbered `after_seq` (0 = from the first), in
  // submission order; `more` if jobs are left after the page's last one (`last_seq`).
  struct JobPage {
    std::vector<photonfarm::v1::JobStatus> jobs;
    uint64_t last_seq = 0;
    bool more = false;
  };
  JobPage ListPage(bool include_finished, uint64_t after_seq, size_t limit);
  // Cancels queued and leased tasks; idempotent for finished jobs (returns their status).
  photonfarm::v1::JobStatus Cancel(const std::string& job_id);
  // Pauses (no new leases; leases in flight finish and are merged) or resumes a queued or running
  // job; idempotent. PreconditionError naming the state for a finished job. In memory only: the
  // caller stores the flag (JobStore::SetJobPaused; docs/farm.md "Pausing a job").
  photonfarm::v1::JobStatus SetPaused(const std::string& job_id, bool paused);
  JobSnapshot Snapshot(const std::string& job_id, bool with_image);
  // Deleting a job (docs/farm.md "Deleting jobs"; scheduler_deletion.cpp). CheckRemovable: the
  // whole id of `job_id` (an id or a unique prefix) if the job may be deleted, else
  // PreconditionError naming its state (only a succeeded, failed or cancelled job; not while a
  // verification of it is with the referee). RemoveJob: the same check, then the job is forgotten —
  // by the registry, the queue, the task sources, worker health, verification and the activity
  // lists — and its config returned (its stored maps are the caller's). Whoever still holds the Job
  // (FindJob is shared) keeps a valid object that nothing reaches any more. The rows and files are
  // the caller's (Persister::DeleteJob).
  std::string CheckRemovable(const std::string& job_id);
  // The whole id of a job id or a unique prefix of one; NotFoundError naming job_id.
  std::string ResolveJobId(const std::string& id_or_prefix);
  std::shared_ptr<const JobConfig> RemoveJob(const std::string& job_id);
  // What RequeueJob starts from (server/scheduling/job_requeue.h): a finished job's config and the
  // checkpoint that holds its merged results. PreconditionError naming the state for a queued or
  // running job (scheduler_deletion.cpp, beside the other check of finished jobs).
  struct FinishedJob {
    std::string job_id;  // the whole id of a prefix
    std::shared_ptr<const JobConfig> config;
    JobState state = JobState::kSucceeded;
    uint64_t tasks_total = 0;  // the plan's tasks, including those a stop rule cancelled
    uint64_t tasks_done = 0;   // merged
    std::string checkpoint_path;
    CheckpointSeal seal;  // of its last checkpoint on disk; its tasks < tasks_done while the final one is not
  };
  FinishedJob FinishedJobOf(const std::string& job_id);
  // The succeeded, failed and cancelled jobs that ended before `cutoff_unix_ms` (Job::finished_unix_ms),
  // the one that ended first first (--data-quota deletes in this order).
  std::vector<std::string> FinishedBefore(int64_t cutoff_unix_ms) const;
  // The configs of every job it knows (which stored maps remaining jobs use).
  std::vector<std::shared_ptr<const JobConfig>> JobConfigs() const;
  // Every job it knows, with its config and whether it is live (queued, running or paused): which
  // stored maps the map store's quota may evict (DistributedMaps::EnforceQuota).
  struct KnownJob {
    std::string id;
    std::shared_ptr<const JobConfig> config;
    bool active = false;
  };
  std::vector<KnownJob> KnownJobs() const;
  // Queued and running jobs, their tasks and pixels, and how many of them `client` submitted
  // (Job::client). O(1).
  ActiveLoad Load(const std::string& client) const;

  // --- Workers ---
  std::optional<Lease> TryLease(const LeaseRequest& request);
  // Calls `done` exactly once: with a lease as soon as one is available (possibly before
  // returning), or with nullopt when `wait_seconds` pass, on CancelWait or on Shutdown.
  uint64_t LeaseOrWait(const LeaseRequest& request, double wait_seconds, LeaseCallback done);
  void CancelWait(uint64_t waiter_id);
  // `worker_id` must be the lease's holder (LeaseRequest.worker_id), else not_holder and nothing
  // changes.
  ExtendResult Extend(const std::string& lease_id, const std::string& worker_id, double progress);
  // Validates and merges (see the header comment). Never throws for bad results: kRejected.
  // `worker_id` must be the lease's holder: kNotHolder (nothing merged, the lease untouched).
  // `part`: the part of the radiance the worker says it rendered (CompleteTaskRequest.part); a
  // result for another part than the task's is rejected (an old worker ignores Task.part).
  CompleteResult Complete(const std::string& lease_id, const std::string& worker_id,
                          std::span<const float> rgb_sums, RadiancePart part = RadiancePart::kAll);
  // Only the holder of a live lease may fail its task: `worker_id` must be the worker it was
  // leased to (LeaseRequest.worker_id). kUnknownLease (expired, replaced, finished or never
  // issued) and kNotHolder change nothing.
  FailOutcome Fail(const std::string& lease_id, const std::string& worker_id, const std::string& reason,
                   bool retryable);
  // A lease that never reached its worker: back to the queue, no failure counted.
  void ReturnLease(const std::string& lease_id);
  // The worker is leaving (LeaveFarm): listed as offline, never marked lost while it is silent.
  void WorkerLeft(const std::string& worker_id);

  // A worker sent a result of the job (a render task or a map piece) that another render proved
  // wrong (docs/farm.md, "Result verification"), or presented another worker's lease. The worker
  // is blocklisted for the job (and counts towards its quarantine), an event says why, and — if
  // its results may be in the job's image or, through its pieces, in its maps (ConvictInJob; a
  // hijack before any of its results merged ends only its leases) — the job starts again from nothing without
  // it (Job::Restart): all of its tasks are queued again and its leases dropped; the job leases nothing until
  // the checkpoint of the empty image and its row (epoch, convicted workers) are stored (a stop rule may
  // still end it meanwhile). A finished job is left as it is (false). `task_id` names the task or piece the
  // evidence is about, for the event. Its pieces leave every stored map first
  // (MapTracingHook::WorkerConvicted), and every other active job that used such a map starts again as well.
  bool ConvictWorker(const std::string& job_id, const std::string& worker_id, uint64_t task_id,
                     const std::string& evidence);
  // A worker presented a lease of the job held by another worker. Worker ids are self-declared, so
  // the presenter may be anyone's name and nothing about a result is proven: the id is blocklisted
  // for this job only (`convicted` event; stored with the job's convictions) and its leases of the
  // job are returned without counting a failure — no quarantine count, no map purged, no restart.
  // An ended job is left as it is.
  void BlocklistForHijack(const std::string& job_id, const std::string& worker_id, uint64_t task_id,
                          const std::string& evidence);
  // Hijackers recorded in a job's stored convictions at most (more are blocklisted in memory only).
  static constexpr size_t kMaxConvictedWorkersPerJob = 256;

  // --- Result verification (result_verification.h; docs/farm.md "Result verification") ---
  // Set before use; `referee` outlives the scheduler's use of it.
  void SetReferee(RefereeHook* referee);
  // The referee's render of a verification's task (RefereeCase): the digest of its result
  // (ResultMerger::Digest), or `error` if it could not render it.
  void RefereeVerdict(uint64_t verification_id, const std::string& digest, const std::string& error = "");
  // Tests only: the source of the random choice (uniform in [0, 1)). Set before use.
  void SetVerificationRandomForTest(std::function<double()> uniform);
  uint32_t JobEpoch(const std::string& job_id) override;
  uint64_t StoredMergeSeq(const std::string& job_id) override;
  // Recovery: the job's convicted workers (JobRow.convicted) are blocklisted for it again.
  void RestoreConvictions(const std::string& job_id, const std::vector<std::string>& workers);
  // The piece a map piece lease names, for its upload (UploadPhotonChunk; `call` names the RPC in
  // logs): the one lease path (FindLiveLease) — an unknown, expired, finished or render-task lease
  // is kNotLive, another worker's is kNotHolder (its presenter blocklisted, as for a task). The
  // caller is heard from (it is live).
  struct PieceLeaseRef {
    enum class Status { kLive, kNotLive, kNotHolder };
    Status status = Status::kNotLive;
    std::string map_key;
    uint32_t piece = 0;
  };
  PieceLeaseRef PieceLeaseOf(const std::string& lease_id, const std::string& worker_id,
                             const std::string& call);

  // --- Time --- expires leases, long polls and time budgets. Call periodically.
  void Tick();

  // --- Persistence (server/store/persist_source.h; the rules: docs/farm.md "Durability") ---
  std::vector<Checkpoint> CollectCheckpoints(bool due) override;
  void CheckpointStored(const Checkpoint& checkpoint, const CheckpointSeal& seal,
                        const std::string& path) override;
  void CheckpointNotStored(const std::string& job_id, uint64_t merge_seq, const std::string& reason) override;
  void ResultsJournaled(const std::string& job_id, std::span<const uint64_t> task_ids) override;
  void ResultsNotStored(const std::string& job_id, const std::string& reason) override;
  void ForceCheckpoint(const std::string& job_id) override;
  RowBatch CollectRows() override;
  void RowsNotStored(const RowBatch& rows, const std::string& reason) override;
  void RowsStored(const RowBatch& rows) override;
  bool HasUncheckpointedMerges();

  // No more leases; parked long polls are answered "no task".
  void Shutdown();

  // --- Photon maps traced once (docs/farm.md, "Photon maps traced once"; map_tracing_hook.h) ---
  // Set before jobs are added; `work` outlives the scheduler's use of it.
  void SetMapTracingHook(MapTracingHook* work);
  // A map event that began outside the Scheduler (an upload refused, an assembly, a conviction):
  // its update applied as the hook's answers are (map_tracing_hook.h) — the maps' queued pieces set
  // in the queue, failed attempts counted against their workers, released maps' render tasks
  // queued — and parked long polls served. Call outside MapTracingHook's own lock.
  void ApplyMapUpdate(const MapUpdate& update);

  SchedulerCounters counters() const;
  const SchedulerOptions& options() const { return options_; }
  // Workers and task events, for people (pf workers, pf events, the web page).
  FarmActivity& activity() { return activity_; }

 private:
  struct Effects {
    std::vector<std::pair<LeaseCallback, std::optional<Lease>>> callbacks;
    std::set<std::string> changed;
    bool persist = false;
    std::vector<RefereeCase> referee;  // verifications for the referee (Run hands them over)
    // Workers that presented a lease held by another worker (NotTheHolderLocked): Run blocklists
    // them (BlocklistForHijack takes the lock itself).
    struct Hijack {
      std::string job_id, worker_id;
      uint64_t task_id = 0;
      std::string evidence;
    };
    std::vector<Hijack> hijacks;
  };
  struct Waiter {
    LeaseRequest request;
    double deadline;
    LeaseCallback done;
  };

  void Run(Effects& effects);  // outside the lock
  // `worker_id` presented the lease of `job_id`'s task `task_id` (`call`: the RPC) while another
  // worker holds it. Lease ids are 128 CSPRNG bits and never logged, and an honest worker keeps
  // its id for the lifetime of its process, so this is a leaked id put to use: the presenter is
  // blocklisted for the job (BlocklistForHijack; docs/security.md, "Leases are bound to their
  // worker"). Logs the refusal.
  // A map piece's lease (`kind`) is refused so in every job of its map.
  void NotTheHolderLocked(const std::string& job_id, uint64_t task_id, const std::string& worker_id,
                          const std::string& holder, const std::string& call, Effects& fx,
                          LeaseKind kind = LeaseKind::kRenderTask);
  void Touch(Job& job, Effects& fx);
  void Enqueue(Job& job, uint64_t task_id, Effects& fx);
  void Dequeue(Job& job, uint64_t task_id);
  void ServeWaiters(Effects& fx);
  // `restricted` (if set) is set when the worker passed work by that another might take (it is
  // quarantined, blocklisted for a job, or left a retry to a waiting worker).
  std::optional<Lease> LeaseLocked(const LeaseRequest& request, double now, Effects& fx,
                                   bool* restricted = nullptr);
  // Worker health (worker_health.h): a poll (it makes the worker known), any other call.
  void PolledLocked(const std::string& worker_id, double now);
  void HeardLocked(const std::string& worker_id, double now);
  // A failed attempt of `worker_id` in the job: blocklist and quarantine. True if it just got
  // blocklisted for the job.
  bool CountFailure(Job& job, const std::string& worker_id, uint64_t task_id, uint32_t attempt,
                    const std::string& reason, double now, bool convicted = false);
  // "" while a live worker not blocklisted for the job is left, or while every blocklisted worker
  // was convicted (the job waits for an honest one), else why none is (naming the blocklisted
  // workers).
  std::string NoWorkerLeft(const Job& job) const;
  // Whether a parked long poll of another worker could take this retry (not blocklisted or
  // quarantined, not one that failed the task already).
  bool AnotherWaiterCanTake(const Job& job, const TaskRuntime& rt, const std::string& worker_id,
                            double now) const;
  // The lease of the task ran out: the attempt fails (and its worker may be lost).
  void ExpireLease(Job& job, uint64_t task_id, double now, Effects& fx);
  bool CheckTimeBudget(Job& job, double now, Effects& fx);
  // A result above the job's bound: "" if it reproduces, bit for bit, the last such result of the
  // task from another worker (then it is merged), else the reason it is rejected (and records it).
  std::string ConfirmImplausible(Job& job, uint64_t task_id, const std::string& digest,
                                 const ResultCheck& check);
  // The current attempt of a leased task ended badly.
  void FailAttempt(Job& job, uint64_t task_id, const std::string& reason, bool retryable, double now,
                   Effects& fx);
  // Ends the job: cancels every queued and leased task, then transitions.
  void FinishJob(Job& job, JobState state, const std::string& reason, double now, Effects& fx);
  void MaybeSucceed(Job& job, double now, Effects& fx);
  // The job, shared: it stays valid without the lock even if it is deleted meanwhile (RemoveJob).
  std::shared_ptr<Job> FindJob(const std::string& job_id);
  // Job dependencies (docs/farm.md "Job dependencies"; scheduler_dependencies.cpp). AddJob: the
  // jobs of the job's spec.after that have not succeeded become its waiting_for (it is held while
  // one is left); returns why it fails instead — one of them failed, was cancelled or is unknown —
  // or "". FinishJob: the live jobs waiting for `job` are released (it succeeded) or failed.
  std::string WaitForDependencies(Job& job);
  void ReleaseDependents(const Job& job, double now, Effects& fx);
  // Brings the cached noise estimate up to date if stale (an O(pixels) pass under image_mu; call
  // without mu_).
  void RefreshNoise(Job& job);
  void RefreshNoiseOfAll(bool include_finished);
  // The one lease path, for both kinds (lease_table.h): the lease if it is current; expires it (and
  // returns null) if it ran out; drops a piece's entry the map hook no longer knows as current.
  LeaseTable::Entry* FindLiveLease(const std::string& lease_id, double now, Effects& fx);
  // A map piece's lease ran out or was failed by its holder: erased, the hook told, its update
  // applied, parked long polls served.
  void EndPieceLeaseLocked(const std::string& lease_id, PieceLeaseEnd::Why why, const std::string& reason,
                           double now, Effects& fx);
  // Photon maps traced once (map_tracing_hook.h). The queued piece a worker gets, leased (before
  // verifications and render tasks); sets *passed if it was passed over a map (blocklisted).
  std::optional<Lease> LeasePieceLocked(const LeaseRequest& request, double now, bool failed_before,
                                        bool* passed);
  // The hook's update (MapUpdate, in its order); ApplyMapUpdate without the lock and the serving.
  void ApplyMapUpdateLocked(const MapUpdate& update, double now, Effects& fx);
  // The map's queued pieces in the queue become those the hook says are queued (QueuedPiecesOf).
  void QueueMapPiecesLocked(const std::string& map_key);
  // A map piece's attempt failed: it counts against the worker in the job like a task's.
  void PieceAttemptFailedLocked(const PieceFailure& failure, double now, Effects& fx);
  // The map `map_index` of the job is built (or left to its workers): its held render tasks join
  // the queue.
  void ReleaseMapLocked(const std::string& job_id, uint64_t map_index, Effects& fx);
  // A call (`call`) with a live lease `entry` of either kind from `worker_id`: false (and the
  // caller refused: NotTheHolderLocked) unless the worker holds it.
  bool HolderLocked(const LeaseTable::Entry& entry, const std::string& worker_id, const std::string& call,
                    Effects& fx);
  // Appends and queues the tasks the job's source creates from its merged results.
  void AddTasksFromSource(Job& job, Effects& fx);
  photonfarm::v1::JobStatus BuildStatus(Job& job, double now);
  // CheckRemovable under the lock: the job, or PreconditionError.
  Job& RemovableLocked(const std::string& job_id);
  // Counts an active job into load_ (AddJob: +1) or its end (FinishJob: −1; its tasks and pixels
  // leave load_ with ReleaseFinishedTasks).
  void Charge(Job& job, int sign);
  // A finished job whose rows and final checkpoint are stored and that no lease pins: drops its
  // task list (Job::ReleaseTasks) and what the scheduler kept per task of it; how many tasks.
  uint64_t ReleaseFinishedTasks(Job& job);
  RowBatch CollectRowsLocked(uint64_t* released_tasks);

  // Result verification (scheduler_verification.cpp).
  bool IsVerificationLease(const std::string& lease_id);
  // A queued verification this worker may take, as a lease (before render tasks); sets *passed if
  // one was queued that it may not take.
  std::optional<Lease> LeaseVerificationLocked(const LeaseRequest& request, double now, Effects& fx,
                                               bool* passed);
  CompleteResult CompleteVerification(const std::string& lease_id, const std::string& worker_id,
                                      std::span<const float> rgb_sums, RadiancePart part);
  // Extend / Fail / ReturnLease of a verification lease (nullopt: not one).
  std::optional<ExtendResult> ExtendVerificationLocked(const std::string& lease_id,
                                                       const std::string& worker_id, double now, Effects& fx);
  std::optional<FailOutcome> FailVerificationLocked(const std::string& lease_id, const std::string& worker_id,
                                                    const std::string& reason, double now, Effects& fx);
  bool ReturnVerificationLocked(const std::string& lease_id, Effects& fx);
  // Queues a verification of a merged result.
  void AddVerificationLocked(Job& job, uint64_t task_id, const std::string& worker, const std::string& digest,
                             const std::string& reason, Effects& fx);
  void VerificationAttemptFailedLocked(ResultVerification::Verification& v, const std::string& reason,
                                       double now, Effects& fx);
  void ExpireVerificationLocked(ResultVerification::Verification& v, double now, Effects& fx);
  void ToRefereeLocked(ResultVerification::Verification& v, Effects& fx);
  // Tick: expired verification leases; jobs waiting only for verifications no worker may do.
  void TickVerificationLocked(double now, Effects& fx);
  // The job has nothing but verifications left: those no live worker may take go to the referee.
  void RefereeIfNoVerifierLocked(Job& job, double now, Effects& fx);
  // The noise target is met: the job succeeds now, or (verifications pending) once they are done,
  // its other tasks cancelled.
  void SucceedOnTarget(Job& job, double now, Effects& fx);
  // Convicts `workers` of the job (ConvictWorker's rule): blocklisted, and the job restarted if its
  // image may hold their work — the evidence is their result merged in the job's current epoch
  // (`result_epoch`: the epoch of the result, given only when its author is among `workers`), a
  // map it used holds their pieces (`used_their_maps`), or a merged task is theirs or of a worker
  // no longer known (recovered tasks). Otherwise their leases of the job are revoked and the job
  // goes on. `verification_id` (if not 0) is removed in the same hold of the locks.
  bool ConvictInJob(Job& job, const std::vector<std::string>& workers, uint64_t task_id,
                    const std::string& evidence, std::optional<uint32_t> result_epoch,
                    uint64_t verification_id, bool used_their_maps);
  // Returns the job's leases (tasks and verifications) held by `workers` to the queue: no failure
  // counted, a `revoked` event saying `why`.
  void RevokeLeasesLocked(Job& job, const std::vector<std::string>& workers, const std::string& why,
                          Effects& fx);
  // ConvictWorker for several workers of one verdict: stored maps purged, then the job and the
  // other jobs that used their maps.
  bool Convict(const std::string& job_id, const std::vector<std::string>& workers, uint64_t task_id,
               const std::string& evidence, std::optional<uint32_t> result_epoch, uint64_t verification_id);

  const Clock& clock_;
  const SchedulerOptions options_;
  mutable std::mutex mu_;
  JobRegistry jobs_;
  ResultMerger merger_;  // thread-safe (its permutation cache has its own lock)
  TaskSourceFactory task_sources_;
  std::unordered_map<const Job*, std::unique_ptr<TaskSource>> sources_;
  TaskQueue queue_;
  LeaseTable leases_;
  std::map<uint64_t, Waiter> waiters_;  // oldest first
  uint64_t next_waiter_ = 1;
  bool shutdown_ = false;
  SchedulerCounters counters_;
  WorkerHealth health_;
  ActiveLoad load_;  // client_jobs unused: per client in client_jobs_
  std::unordered_map<std::string, uint64_t> client_jobs_;
  FarmActivity activity_;
  std::function<void(const std::string&)> change_listener_;
  std::function<void()> persist_listener_;
  MapTracingHook* map_hook_ = nullptr;
  ResultVerification verification_;
  RefereeHook* referee_ = nullptr;
  // Render tasks waiting for their map (MapTracingHook::RenderTaskReady), by job and map index.
  std::map<std::pair<std::string, uint64_t>, std::vector<uint64_t>> held_;
};

}  // namespace pf::server
