#pragma once
// pf-worker's pull loop as an explicit state machine (docs/design.md, S6):
//
//   connecting ──ready──▶ idle (LeaseTask long poll) ──task──▶ fetching-scene ──▶ building-map
//       ▲   │                 │  ▲ no task now                                      │ (cache miss)
//       │   ▼ unreachable     │  └──────────────────┐                               ▼
//     backoff (jittered) ◀────┘ UNAVAILABLE        reporting (CompleteTask) ◀── rendering
//
// and `stopping` after SIGTERM. Every RPC has a deadline. From the lease until the result is ready
// (the scene and map fetches, a piece's trace and upload, the render on a thread of its own using
// all the worker's threads), a heartbeat thread extends the lease every third of its duration; if
// the coordinator answers that the lease is gone, the task is abandoned (the render cancelled) (it
// stops within a block of pixels or a chunk of photons). Results are the subset's pixel sums only
// (common/plan/task_executor.h), never a full image. A finished result survives a coordinator outage:
// CompleteTask is retried with backoff for `report_retry_seconds`.
//
// SIGTERM (RequestStop): no new leases; the current task is finished and reported if that
// happens within `grace_seconds`, else its lease is handed back with FailTask(retryable).
// A second signal (RequestAbort) hands it back at once. Run() then returns 0.
//
// Log lines (one per event, grep-able; the e2e tests count them):
//   leased job=J task=T attempt=A ...       completed job=J task=T attempt=A merged=true|false ...
//   abandoned job=J task=T attempt=A: ...   failed job=J task=T attempt=A retryable=R: reason
//   handed-back job=J task=T attempt=A: ... state X -> Y

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>

#include "common/plan/task_executor.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "rpc/grpc_channel.h"
#include "worker/map_disk_cache.h"
#include "worker/scene_cache.h"
#include "worker/worker_faults.h"

namespace pf::worker {

enum class State {
  kConnecting,
  kBackoff,
  kIdle,
  kFetchingScene,
  kBuildingMap,
  kRendering,
  kReporting,
  kStopping
};
const char* StateName(State s);

struct WorkerOptions {
  std::string coordinator;  // HOST:PORT
  std::string token;        // bearer token, "" = none
  ClientTls tls;            // TLS to the coordinator (plaintext if tls.ca_pem is empty)
  std::string worker_id;
  int threads = 1;                     // > 0
  std::filesystem::path cache_dir;     // scene bundles by hash
  double poll_seconds = 10;            // LeaseTask long-poll wait (≤ 30)
  double rpc_timeout_seconds = 10;     // deadline of short calls
  double fetch_timeout_seconds = 120;  // deadline of FetchScene
  double grace_seconds = 30;           // SIGTERM: finish the task if it ends within this
  double max_backoff_seconds = 5;      // cap of the jittered reconnect backoff
  double report_retry_seconds = 60;    // keep retrying CompleteTask while the coordinator is away
  size_t map_cache_capacity = 4;       // photon maps kept (LRU)
  size_t scene_cache_capacity = 2;     // SceneRuntimes kept in memory (LRU)
  uint64_t max_tasks = 0;  // exit 0 after this many reported tasks (0 = never); for batch schedulers
  // Built maps fetched from the coordinator, on disk by content address (LRU).
  std::filesystem::path map_cache_dir;           // "" = <cache_dir>/maps
  uint64_t map_cache_bytes = uint64_t(4) << 30;  // 0 = keep none on disk
  // Tests only (worker_faults.h): kill points, corrupted arrivals, tampered results. Null in
  // pf-worker.
  std::shared_ptr<WorkerFaults> faults;
};

struct WorkerCounters {
  uint64_t leased = 0, completed = 0, merged = 0, failed = 0, abandoned = 0, handed_back = 0;
  uint64_t cancelled = 0;  // abandoned tasks whose render was stopped before its end
  uint64_t chunks_traced = 0, maps_fetched = 0, maps_from_disk = 0, map_parts_refused = 0;
};

// Run()'s exit code when the coordinator refuses this worker's build (LeaseTask
// FAILED_PRECONDITION: LeaseTaskRequest.worker_version, docs/farm.md "Upgrades"). Waiting would
// not help — the binary cannot change — so the worker exits and its supervisor sees why.
inline constexpr int kExitRefusedBuild = 4;

class Worker {
 public:
  explicit Worker(WorkerOptions options);
  ~Worker();
  Worker(const Worker&) = delete;
  Worker& operator=(const Worker&) = delete;

  // The pull loop; returns the exit code (0 after a stop request or max_tasks,
  // kExitRefusedBuild when the coordinator refuses this build).
  int Run();
  // Thread-safe (called from the signal thread, not from a signal handler).
  void RequestStop();
  void RequestAbort();

  State state() const { return state_.load(); }
  WorkerCounters counters() const;
  // True if Run() returned while a render thread was still busy (its lease was handed back):
  // the caller should end the process with _exit rather than wait for it.
  bool render_in_flight() const { return render_in_flight_.load(); }

 private:
  struct Execution;
  enum class Outcome { kDone, kConnectionLost, kStop };
  // Keeps one task's lease alive on a thread of its own from the moment the task is leased until
  // it is reported: the scene and map fetches and a piece's upload included, not only the render
  // (a large map's fetch can take a good part of the lease). Stop() (or the destructor) ends it.
  class LeaseKeeper {
   public:
    LeaseKeeper(Worker* worker, const photonfarm::v1::Task& task, std::string ctx,
                std::shared_ptr<Execution> exec);
    LeaseKeeper(const LeaseKeeper&) = delete;
    LeaseKeeper& operator=(const LeaseKeeper&) = delete;
    ~LeaseKeeper() { Stop(); }
    void Stop();
    // The coordinator said the lease is gone: whatever is still to do for the task is wasted.
    bool lost() const;

   private:
    std::shared_ptr<Execution> exec_;
    std::thread thread_;
  };
  // A task's shared execution state (defined in worker.cpp); lease_seconds <= 0 means 30 s.
  static std::shared_ptr<Execution> NewExecution(uint64_t pixels, double lease_seconds);

  void SetState(State s, const std::string& context = "");
  bool WaitForConnection();
  void BackoffSleep();
  // Returns nullopt on "no task now"; sets *status on RPC failure.
  std::optional<photonfarm::v1::Task> Lease(grpc::Status* status);
  // A task's fields in core types (RunTask parses them first).
  struct ParsedTask {
    CameraSpec camera;
    JobRenderSettings settings;
    TaskSpec spec;
    uint64_t pixels = 0;  // in the task's subset
  };

  // One leased task, start to end; its steps, in order, follow.
  Outcome RunTask(const photonfarm::v1::Task& task);
  // nullopt: the task could not be read and was failed (permanently).
  std::optional<ParsedTask> ParseTask(const photonfarm::v1::Task& task, const std::string& ctx);
  // nullopt: *scene is set; else the task ended here and the outcome says how.
  std::optional<Outcome> GetScene(const photonfarm::v1::Task& task, const std::string& ctx,
                                  std::shared_ptr<const SceneRuntime>* scene);
  // Logs what the job's `auto` settings resolve to, once per job.
  void LogAutoSettings(const photonfarm::v1::Task& task, const std::string& ctx,
                       const JobRenderSettings& settings, const SceneRuntime& scene);
  Outcome ExecuteSupervised(const photonfarm::v1::Task& task, const std::string& ctx,
                            const ParsedTask& parsed, std::shared_ptr<const SceneRuntime> scene,
                            std::chrono::steady_clock::time_point t0, std::shared_ptr<Execution> exec,
                            LeaseKeeper& keeper);
  static std::thread StartRender(std::shared_ptr<Execution> exec, std::shared_ptr<const SceneRuntime> scene,
                                 const ParsedTask& parsed, const std::string& scene_hash,
                                 std::shared_ptr<PhotonMapCache> maps, int threads);
  bool SuperviseUntilHandBack(const std::string& ctx, Execution& exec, bool* abandoned_logged,
                              bool* lease_lost);
  Outcome FinishExecution(const photonfarm::v1::Task& task, const std::string& ctx, Execution& exec,
                          bool abandoned_logged, std::chrono::steady_clock::time_point t0);
  Outcome Report(const photonfarm::v1::Task& task, const std::string& ctx, const TaskOutput& output);
  // Logs and counts a failure, then tells the coordinator (SendFail).
  void Fail(const photonfarm::v1::Task& task, const std::string& ctx, const std::string& reason,
            bool retryable);
  void SendFail(const photonfarm::v1::Task& task, const std::string& ctx, const std::string& reason,
                bool retryable);
  void Heartbeat(const photonfarm::v1::Task& task, const std::string& ctx, std::shared_ptr<Execution> exec);
  SceneBundle FetchBundle(const std::string& hash, const std::string& entry);
  // A piece of a map to trace and upload; a built map to fetch.
  Outcome RunTraceChunk(const photonfarm::v1::Task& task);
  // Puts the task's map (Task.map) into maps_ from disk or by FetchMap, unless tracing it here is
  // faster (cost model, logged); returns nullopt to go on rendering.
  std::optional<Outcome> ObtainMap(const photonfarm::v1::Task& task, const std::string& ctx,
                                   const ParsedTask& parsed, const SceneRuntime& scene);
  std::string FetchMapBytes(const photonfarm::v1::MapRef& ref, const std::string& ctx);
  bool UploadChunk(const photonfarm::v1::Task& task, const std::string& ctx, const std::string& bytes,
                   grpc::Status* status);
  // Maps in maps_ that came from the coordinator (fetched or from the disk cache), by cache key,
  // with the digest (MapRef.digest) they were fetched under: such a map is used only for a task
  // whose Task.map names that digest — a map the coordinator traced again after a conviction has
  // another (docs/farm.md "Result verification"), and a task without Task.map traces its own.
  void NoteFetchedMap(const std::string& cache_key, const std::string& digest);
  // Drops the map of `cache_key` from maps_ if it was fetched under another digest than `digest`
  // ("" : any fetched map). True if dropped.
  bool ForgetFetchedMap(const std::string& cache_key, const std::string& digest);
  void ObserveTracing(uint64_t photons, double seconds);
  // The injected faults' kill point (WorkerFaults::At); nothing without faults.
  void FaultPoint(const char* where, const std::string& ctx) {
    if (options_.faults) options_.faults->At(where, ctx);
  }

  bool stop_requested() const { return stop_.load(); }
  // Sleeps up to `d`, returning early (true) when stop/abort is requested.
  bool InterruptibleSleep(std::chrono::milliseconds d, bool wake_on_stop = true);

  WorkerOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<photonfarm::v1::WorkerService::Stub> stub_;
  SceneCache scenes_;
  MapDiskCache map_disk_;
  // Cost model of trace-or-fetch (docs/farm.md, "Photon maps traced once"), measured here: seconds per photon
  // of tracing and building a map with options_.threads, and bytes per second of fetches. 0 = not measured
  // yet.
  double seconds_per_photon_ = 0, bytes_per_second_ = 0;
  std::map<std::string, std::string> fetched_maps_;  // NoteFetchedMap; guarded by mutex_
  std::shared_ptr<PhotonMapCache> maps_;  // shared with a render thread that may outlive a hand-back

  std::atomic<State> state_{State::kConnecting};
  std::atomic<bool> stop_{false}, abort_{false}, render_in_flight_{false};
  std::chrono::steady_clock::time_point stop_deadline_;
  int failures_ = 0;             // consecutive connection failures (backoff exponent)
  std::string auto_logged_job_;  // the last job whose `auto` settings were logged
  std::mt19937_64 jitter_rng_;

  mutable std::mutex mutex_;                     // guards poll_context_, counters_, stop_deadline_
  std::condition_variable wake_;                 // stop/abort/execution progress
  grpc::ClientContext* poll_context_ = nullptr;  // the LeaseTask in flight, cancelled on stop
  WorkerCounters counters_;
};

}  // namespace pf::worker
