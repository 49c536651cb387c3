#pragma once
// pf-worker's pull loop as an explicit state machine (docs/design.md, S6):
//
//   connecting ──ready──▶ idle (LeaseTask long poll) ──task──▶ fetching-scene ──▶ building-map
//       ▲   │                 │  ▲ no task now                                      │ (cache miss)
//       │   ▼ unreachable     │  └──────────────────┐                               ▼
//     backoff (jittered) ◀────┘ UNAVAILABLE        reporting (CompleteTask) ◀── rendering
//
// and `stopping` after SIGTERM. The states and every legal move between them are a checked table
// (worker_state.h): SetState throws std::logic_error on a move the table does not hold. A map
// piece goes idle → fetching-scene → building-map (its trace) → reporting (its upload).
//
// The loop, its steps and who does them:
//   lease (coordinator_client.h: every RPC with its deadline and retries, checks of what arrives)
//   → scene (scene_obtainer.h) → map (map_obtainer.h: memory, disk, FetchMap or traced here)
//   → execute (task_execution.h: the render on a thread of its own using all the worker's
//     threads; lease_keeper.h: a heartbeat from the lease until the report) → report.
// From the lease until the result is ready, the heartbeat extends the lease every third of its
// duration; if the coordinator answers that the lease is gone, the task is abandoned (the render
// cancelled: it stops within a block of pixels or a chunk of photons). Results are the subset's
// pixel sums only (common/plan/task_executor.h), never a full image. A finished result survives a
// coordinator outage: CompleteTask is retried with backoff (backoff.h) for `report_retry_seconds`.
//
// SIGTERM (RequestStop): no new leases; the current task is finished and reported if that
// happens within `grace_seconds`, else its lease is handed back with FailTask(retryable).
// A second signal (RequestAbort) hands it back at once. Run() then returns 0.
//
// Log lines (one per event, grep-able; the e2e tests count them):
//   leased job=J task=T attempt=A ...       completed job=J task=T attempt=A merged=true|false ...
//   abandoned job=J task=T attempt=A: ...   failed job=J task=T attempt=A retryable=R: reason
//   handed-back job=J task=T attempt=A: ... state X -> Y (debug)

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "photonfarm/v1/farm.pb.h"
#include "worker/backoff.h"
#include "worker/coordinator_client.h"
#include "worker/lease_keeper.h"
#include "worker/leased_task.h"
#include "worker/map_obtainer.h"
#include "worker/scene_obtainer.h"
#include "worker/task_execution.h"
#include "worker/worker_options.h"
#include "worker/worker_state.h"

namespace pf::worker {

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
  enum class Outcome { kDone, kConnectionLost, kStop };

  // Moves to `s` after checking the move (WorkerTransitions); logs it at debug level.
  void SetState(State s, const std::string& context = "");
  bool WaitForConnection();
  // Sleeps the next backoff; a stop request ends the sleep early unless `wake_on_stop` is false
  // (a retry loop that keeps running after the request, until its own deadline).
  void BackoffSleep(bool wake_on_stop = true);
  // Returns nullopt on "no task now"; sets *status on RPC failure.
  std::optional<photonfarm::v1::Task> Lease(grpc::Status* status);

  // One leased render task, start to end; its steps, in order, follow.
  Outcome RunTask(const photonfarm::v1::Task& task);
  // The scene step: fetching-scene. nullopt: *scene is set.
  std::optional<Outcome> ObtainScene(const photonfarm::v1::Task& task, const std::string& ctx,
                                     std::shared_ptr<const SceneRuntime>* scene);
  // Logs what the job's `auto` settings resolve to, once per job.
  void LogAutoSettings(const photonfarm::v1::Task& task, const std::string& ctx,
                       const JobRenderSettings& settings, const SceneRuntime& scene);
  // The map step (photon-map tasks): building-map unless the map is in memory. nullopt: render.
  std::optional<Outcome> ObtainMap(const photonfarm::v1::Task& task, const std::string& ctx,
                                   const ParsedTask& parsed, const SceneRuntime& scene);
  // Render on a thread of its own so that this thread can watch the lease, the grace period and
  // the stop requests.
  Outcome ExecuteSupervised(const photonfarm::v1::Task& task, const std::string& ctx,
                            const ParsedTask& parsed, std::shared_ptr<const SceneRuntime> scene,
                            std::chrono::steady_clock::time_point t0, std::shared_ptr<TaskExecution> exec,
                            LeaseKeeper& keeper);
  bool SuperviseUntilHandBack(const std::string& ctx, TaskExecution& exec, bool* abandoned_logged,
                              bool* lease_lost);
  Outcome FinishExecution(const photonfarm::v1::Task& task, const std::string& ctx, TaskExecution& exec,
                          bool abandoned_logged, std::chrono::steady_clock::time_point t0);
  Outcome Report(const photonfarm::v1::Task& task, const std::string& ctx, const TaskOutput& output);
  // A piece of a map to trace and upload (Task.trace_chunk).
  Outcome RunMapPiece(const photonfarm::v1::Task& task);

  // A step ended the task: Fail it, or leave the lease to expire while the coordinator is away.
  Outcome End(const photonfarm::v1::Task& task, const std::string& ctx, const TaskEnd& end);
  // Logs and counts a failure, then tells the coordinator (FailTask).
  void Fail(const photonfarm::v1::Task& task, const std::string& ctx, const std::string& reason,
            bool retryable);
  // The task's lease is gone before its end: logged ("abandoned CTX: WHY"), counted, nothing sent.
  Outcome Abandon(const std::string& ctx, const char* why);

  bool stop_requested() const { return stop_.load(); }
  // Sleeps up to `d`, returning early (true) when stop/abort is requested.
  bool InterruptibleSleep(std::chrono::milliseconds d, bool wake_on_stop = true);

  WorkerOptions options_;
  CoordinatorClient client_;
  SceneObtainer scenes_;
  MapObtainer maps_;

  std::atomic<State> state_{State::kConnecting};
  std::atomic<bool> stop_{false}, abort_{false}, render_in_flight_{false};
  std::chrono::steady_clock::time_point stop_deadline_;
  Backoff backoff_;              // reconnects and CompleteTask retries
  std::string auto_logged_job_;  // the last job whose `auto` settings were logged

  mutable std::mutex mutex_;      // guards counters_, stop_deadline_
  std::condition_variable wake_;  // stop/abort
  WorkerCounters counters_;
};

}  // namespace pf::worker
