#include "worker/worker.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <random>
#include <thread>

#include "common/core/error.h"
#include "common/photon/photon_chunk.h"
#include "proto/convert.h"
#include "rpc/tls_diagnosis.h"

namespace pf::worker {
namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

namespace {

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

Worker::Worker(WorkerOptions options)
    : options_(std::move(options)),
      client_(options_),
      scenes_(client_, options_.cache_dir, options_.scene_cache_capacity),
      maps_(client_, options_),
      backoff_(options_.max_backoff_seconds, std::random_device{}()) {}

Worker::~Worker() = default;

void Worker::SetState(State s, const std::string& context) {
  const State old = state_.load();
  if (old == s) return;
  WorkerTransitions().Check(old, s);
  state_ = s;  // only the loop's thread moves the state; others read it
  if (context.empty())
    spdlog::debug("state {} -> {}", StateName(old), StateName(s));
  else
    spdlog::debug("state {} -> {} {}", StateName(old), StateName(s), context);
}

WorkerCounters Worker::counters() const {
  WorkerCounters c;
  {
    std::lock_guard lock(mutex_);
    c = counters_;
  }
  c.maps_fetched = maps_.fetched();
  c.maps_from_disk = maps_.from_disk();
  c.map_parts_refused = client_.map_parts_refused();
  return c;
}

void Worker::RequestStop() {
  {
    std::lock_guard lock(mutex_);
    if (stop_.load()) return;
    stop_deadline_ = Clock::now() + Seconds(options_.grace_seconds);
    stop_ = true;
    wake_.notify_all();
  }
  client_.CancelPolls();
  spdlog::info("stop requested: finishing the current task within {:.0f}s grace, no new leases",
               options_.grace_seconds);
}

void Worker::RequestAbort() {
  {
    std::lock_guard lock(mutex_);
    stop_deadline_ = Clock::now();
    stop_ = true;
    abort_ = true;
    wake_.notify_all();
  }
  client_.CancelPolls();
  spdlog::info("abort requested: handing back the current lease now");
}

bool Worker::InterruptibleSleep(std::chrono::milliseconds d, bool wake_on_stop) {
  std::unique_lock lock(mutex_);
  return wake_.wait_for(lock, d, [&] { return abort_.load() || (wake_on_stop && stop_.load()); });
}

void Worker::BackoffSleep(bool wake_on_stop) {
  SetState(State::kBackoff);
  const auto wait = std::chrono::duration_cast<std::chrono::milliseconds>(Seconds(backoff_.NextSeconds()));
  if (wake_on_stop) {
    InterruptibleSleep(wait);
    return;
  }
  // Not ended by a stop request, but never past its grace period (also one that arrives while
  // it sleeps: a notification recomputes the end).
  const Clock::time_point end = Clock::now() + wait;
  std::unique_lock lock(mutex_);
  while (!abort_.load()) {
    const Clock::time_point until = stop_.load() ? std::min(end, stop_deadline_) : end;
    if (Clock::now() >= until) break;
    wake_.wait_until(lock, until);
  }
}

bool Worker::WaitForConnection() {
  SetState(State::kConnecting);
  while (!stop_requested()) {
    if (client_.WaitForConnected(std::chrono::milliseconds(500))) {
      if (backoff_.failures() > 0) spdlog::info("connected to coordinator {}", options_.coordinator);
      return true;
    }
    if (backoff_.failures() == 0 || backoff_.failures() % 20 == 0) {
      // Over TLS, "unreachable" may be a refused certificate: say so (rpc/tls_diagnosis.h).
      const std::string why = DiagnoseTlsHandshake(options_.coordinator, options_.tls);
      if (!why.empty())
        spdlog::error("{}; retrying with backoff", why);
      else
        spdlog::warn("coordinator {} unreachable; retrying with backoff", options_.coordinator);
    }
    BackoffSleep();
    SetState(State::kConnecting);
  }
  return false;
}

std::optional<v1::Task> Worker::Lease(grpc::Status* status) {
  SetState(State::kIdle);
  std::optional<v1::Task> task;
  *status = client_.LeaseTask(maps_.memory()->CachedSeeds(), &task);
  return task;
}

int Worker::Run() {
  spdlog::info("worker {} starting: coordinator {}, {} threads, cache {}", options_.worker_id,
               options_.coordinator, options_.threads, options_.cache_dir.string());
  uint64_t reported = 0;
  int exit_code = 0;
  while (!stop_requested()) {
    if (!WaitForConnection()) break;
    grpc::Status status;
    std::optional<v1::Task> task = Lease(&status);
    if (!status.ok()) {
      if (stop_requested()) break;
      if (status.error_code() == grpc::StatusCode::FAILED_PRECONDITION &&
          status.error_message().rfind("worker_version:", 0) == 0) {
        // Another build (docs/farm.md, "Upgrades"): polling again cannot change this binary.
        spdlog::error("LeaseTask: {}; exiting (code {})", StatusToString(status), kExitRefusedBuild);
        exit_code = kExitRefusedBuild;
        break;
      }
      if (status.error_code() == grpc::StatusCode::UNAUTHENTICATED ||
          status.error_code() == grpc::StatusCode::PERMISSION_DENIED) {
        // A wrong token will not fix itself, but an operator may rotate it: keep trying slowly.
        spdlog::error("LeaseTask: {} (check --token-file / PF_TOKEN)", StatusToString(status));
        backoff_.Slowest();
      } else if (IsConnectionError(status)) {
        spdlog::warn("LeaseTask: {}", StatusToString(status));
      } else if (status.error_code() == grpc::StatusCode::CANCELLED) {
        // Not our stop (checked above): the coordinator ended the call, as a clean shutdown or
        // restart does with parked long polls. Nothing is wrong here; reconnect.
        spdlog::info("LeaseTask: the coordinator closed the call ({}); reconnecting", status.error_message());
      } else {
        spdlog::error("LeaseTask: {}", StatusToString(status));
      }
      BackoffSleep();
      continue;
    }
    backoff_.Reset();
    if (!task) continue;  // no task now: poll again
    {
      std::lock_guard lock(mutex_);
      ++counters_.leased;
    }
    const Outcome outcome = task->has_trace_chunk() ? RunMapPiece(*task) : RunTask(*task);
    if (outcome == Outcome::kStop) break;
    if (outcome == Outcome::kConnectionLost) BackoffSleep();
    ++reported;
    if (options_.max_tasks > 0 && reported >= options_.max_tasks) {
      spdlog::info("reached --max-tasks {}: exiting", options_.max_tasks);
      break;
    }
  }
  SetState(State::kStopping);
  // Said as it leaves, so that the coordinator lists it offline rather than lost; not after an
  // abort (exit now) or a refusal of its build (it never joined).
  if (exit_code == 0 && !abort_.load()) client_.LeaveFarm();
  const WorkerCounters c = counters();
  spdlog::info(
      "worker {} stopped: {} leased, {} completed ({} merged), {} failed, {} abandoned ({} cancelled), {} "
      "handed back",
      options_.worker_id, c.leased, c.completed, c.merged, c.failed, c.abandoned, c.cancelled, c.handed_back);
  return exit_code;
}

// A render task: read it, get its scene (fetching-scene), log the settings chosen for `auto`, get
// its map (building-map), then render it on a thread of its own under supervision (lease, grace
// period, stop requests) and report.
Worker::Outcome Worker::RunTask(const v1::Task& task) {
  const std::string ctx = TaskContext(task);
  const Clock::time_point t0 = Clock::now();
  ParsedTask parsed;
  try {  // a task we cannot even read goes straight back as a permanent failure
    parsed = ParseTask(task);
  } catch (const InputError& e) {
    Fail(task, ctx, e.what(), false);
    return Outcome::kDone;
  }
  parsed.pixels = CountTaskPixels(parsed);
  spdlog::info("leased {} map={} pixels={} samples={} lease={:.1f}s", ctx, task.map_index(), parsed.pixels,
               parsed.spec.sample_end - parsed.spec.sample_begin, task.lease_seconds());
  auto exec = std::make_shared<TaskExecution>(parsed.pixels, task.lease_seconds());
  LeaseKeeper keeper(client_, task.lease_id(), ctx, exec);
  std::shared_ptr<const SceneRuntime> scene;
  if (const std::optional<Outcome> ended = ObtainScene(task, ctx, &scene)) return *ended;
  LogAutoSettings(task, ctx, parsed.settings, *scene);
  if (const std::optional<Outcome> ended = ObtainMap(task, ctx, parsed, *scene)) return *ended;
  // e.g. the fetches outlasted a lease the coordinator could not extend
  if (keeper.lost()) return Abandon(ctx, "the lease is gone before the render started");
  if (options_.faults) options_.faults->At("render", ctx);
  return ExecuteSupervised(task, ctx, parsed, std::move(scene), t0, std::move(exec), keeper);
}

std::optional<Worker::Outcome> Worker::ObtainScene(const v1::Task& task, const std::string& ctx,
                                                   std::shared_ptr<const SceneRuntime>* scene) {
  SetState(State::kFetchingScene, ctx);
  if (const std::optional<TaskEnd> end = scenes_.Obtain(task, ctx, scene)) return End(task, ctx, *end);
  return std::nullopt;
}

void Worker::LogAutoSettings(const v1::Task& task, const std::string& ctx, const JobRenderSettings& settings,
                             const SceneRuntime& scene) {
  if (task.job_id() == auto_logged_job_ || settings.integrator != IntegratorKind::kPhotonMap) return;
  auto_logged_job_ = task.job_id();  // once per job (every task resolves alike, ExecuteTask)
  std::vector<AutoChoice> choices;
  settings.Resolved(scene.description, &choices);
  for (const AutoChoice& c : choices) spdlog::info("{}: auto {} = {}: {}", ctx, c.setting, c.value, c.reason);
}

std::optional<Worker::Outcome> Worker::ObtainMap(const v1::Task& task, const std::string& ctx,
                                                 const ParsedTask& parsed, const SceneRuntime& scene) {
  if (parsed.settings.integrator != IntegratorKind::kPhotonMap) return std::nullopt;
  const std::string cache_key =
      MapCacheKey(task.scene_hash(), parsed.settings.Resolved(scene.description), parsed.spec.map_seed);
  if (!task.has_map()) {
    maps_.ForgetFetched(cache_key);
    return std::nullopt;
  }
  if (maps_.InMemory(cache_key, task.map(), ctx)) return std::nullopt;
  SetState(State::kBuildingMap, ctx);
  if (const std::optional<TaskEnd> end =
          maps_.Obtain(cache_key, task.map(), ctx, parsed.settings.photons, parsed.spec.map_seed))
    return End(task, ctx, *end);
  return std::nullopt;
}

Worker::Outcome Worker::ExecuteSupervised(const v1::Task& task, const std::string& ctx,
                                          const ParsedTask& parsed, std::shared_ptr<const SceneRuntime> scene,
                                          Clock::time_point t0, std::shared_ptr<TaskExecution> exec,
                                          LeaseKeeper& keeper) {
  const std::vector<uint64_t> cached = maps_.memory()->CachedSeeds();
  const bool map_cached = parsed.settings.integrator == IntegratorKind::kPath ||
                          std::find(cached.begin(), cached.end(), parsed.spec.map_seed) != cached.end();
  SetState(map_cached ? State::kRendering : State::kBuildingMap, ctx);
  render_in_flight_ = true;
  std::thread render =
      StartRender(exec, std::move(scene), parsed, task.scene_hash(), maps_.memory(), options_.threads);

  bool abandoned_logged = false, lease_lost = false;
  if (SuperviseUntilHandBack(ctx, *exec, &abandoned_logged, &lease_lost)) {
    keeper.Stop();
    if (!lease_lost) {
      spdlog::info("handed-back {}: shutting down before the task finished", ctx);
      client_.FailTask(task.lease_id(), ctx, "worker " + options_.worker_id + " shutting down", true);
      std::lock_guard slock(mutex_);
      ++counters_.handed_back;
    }
    exec->cancel = true;  // the detached render stops soon instead of using the cores to the end
    render.detach();      // render_in_flight_ stays true: main() exits without waiting for it
    return Outcome::kStop;
  }
  render.join();
  render_in_flight_ = false;
  keeper.Stop();
  return FinishExecution(task, ctx, *exec, abandoned_logged, t0);
}

// Watches the render until it is done (false) or the task must be handed back because of a stop
// request past its grace period or an abort (true). Cancels the render once the lease is lost.
bool Worker::SuperviseUntilHandBack(const std::string& ctx, TaskExecution& exec, bool* abandoned_logged,
                                    bool* lease_lost) {
  while (true) {
    std::unique_lock lock(exec.mutex);
    exec.cv.wait_for(lock, std::chrono::milliseconds(100), [&] { return exec.done; });
    if (exec.done) return false;
    *lease_lost = exec.lease_lost;
    lock.unlock();
    if (state() == State::kBuildingMap && exec.progress.load() > 0) SetState(State::kRendering, ctx);
    if (*lease_lost && !*abandoned_logged) {
      *abandoned_logged = true;
      exec.cancel = true;
      spdlog::warn("abandoned {}: the coordinator says the lease is gone; rendering cancelled", ctx);
    }
    std::lock_guard slock(mutex_);
    if (stop_.load() && (abort_.load() || Clock::now() >= stop_deadline_)) return true;
  }
}

// After the render thread ended: drop the result if the lease is gone, fail the task if the
// render failed, else report it.
Worker::Outcome Worker::FinishExecution(const v1::Task& task, const std::string& ctx, TaskExecution& exec,
                                        bool abandoned_logged, Clock::time_point t0) {
  std::unique_lock lock(exec.mutex);
  if (exec.lease_lost) {
    std::lock_guard slock(mutex_);
    ++counters_.abandoned;
    counters_.cancelled += exec.cancelled;
    if (!abandoned_logged) spdlog::warn("abandoned {}: the lease is gone; result dropped", ctx);
    return Outcome::kDone;
  }
  if (!exec.output) {
    const std::string error = exec.error;
    const bool retryable = exec.error_retryable;
    lock.unlock();
    Fail(task, ctx, error, retryable);
    return Outcome::kDone;
  }
  const TaskOutput output = std::move(*exec.output);
  lock.unlock();
  if (!output.map_cache_hit && output.photons_emitted > 0)
    maps_.ObserveTracing(output.photons_emitted, output.map_seconds);
  spdlog::info("rendered {} pixels={} map_cache_hit={} map_s={:.3f} render_s={:.3f} total_s={:.3f}", ctx,
               output.pixels, output.map_cache_hit, output.map_seconds, output.render_seconds,
               SecondsSince(t0));
  return Report(task, ctx, output);
}

Worker::Outcome Worker::Report(const v1::Task& task, const std::string& ctx, const TaskOutput& output) {
  SetState(State::kReporting, ctx);
  // The result is kept while the coordinator is away (it may come back with the lease).
  CoordinatorClient::RetryWhileAway retry;
  retry.give_up = Clock::now() + Seconds(options_.report_retry_seconds);
  retry.stop = [this] {
    std::lock_guard lock(mutex_);
    return abort_.load() || (stop_.load() && Clock::now() >= stop_deadline_);
  };
  retry.until = [this] {
    std::lock_guard lock(mutex_);
    return stop_.load() ? stop_deadline_ : Clock::time_point::max();
  };
  retry.wait = [this, &ctx](int attempts) {
    backoff_.AtLeast(attempts);
    // Not woken by a stop request: the result is still retried until the grace period ends
    // (retry.stop), and a sleep that returned at once made that a busy loop.
    BackoffSleep(/*wake_on_stop=*/false);
    SetState(State::kReporting, ctx);
  };
  const CoordinatorClient::Completion c = client_.CompleteTask(task, output, ctx, retry);
  if (c.status.ok()) {
    spdlog::info("completed {} merged={} bytes={} pixels={}", ctx, c.merged ? "true" : "false", c.bytes,
                 output.pixels);
    std::lock_guard lock(mutex_);
    ++counters_.completed;
    counters_.merged += c.merged;
    return Outcome::kDone;
  }
  if (!IsConnectionError(c.status)) {
    spdlog::error("completed {} merged=false rejected: {}", ctx, StatusToString(c.status));
    std::lock_guard lock(mutex_);
    ++counters_.completed;
    return Outcome::kDone;
  }
  spdlog::error("dropped result of {} after {} attempts: {}", ctx, c.attempts, StatusToString(c.status));
  return stop_requested() ? Outcome::kStop : Outcome::kConnectionLost;
}

// A map piece: read it, get the scene, trace the piece (building-map), upload it (reporting).
Worker::Outcome Worker::RunMapPiece(const v1::Task& task) {
  const v1::TraceChunk& piece = task.trace_chunk();
  const std::string ctx = PieceContext(task);
  JobRenderSettings settings;  // the piece was counted as leased by Run, as every task is
  try {
    settings = SettingsFromProto(task.settings(), "task.settings");
    if (piece.photon_end() <= piece.photon_begin() || piece.photon_end() > settings.photons ||
        piece.photon_begin() % kPhotonTracingChunk != 0)
      throw InputError("task.trace_chunk: photons [" + std::to_string(piece.photon_begin()) + ", " +
                       std::to_string(piece.photon_end()) + ") are not a piece of the map");
  } catch (const InputError& e) {
    Fail(task, ctx, e.what(), false);
    return Outcome::kDone;
  }
  spdlog::info("leased-piece {} photons=[{}, {}) lease={:.1f}s", ctx, piece.photon_begin(),
               piece.photon_end(), task.lease_seconds());
  // The lease is kept alive from here to the upload's end (scene fetch, trace, upload).
  LeaseKeeper keeper(client_, task.lease_id(), ctx, std::make_shared<TaskExecution>(1, task.lease_seconds()));
  std::shared_ptr<const SceneRuntime> scene;
  if (const std::optional<Outcome> ended = ObtainScene(task, ctx, &scene)) return *ended;
  SetState(State::kBuildingMap, ctx);
  std::string bytes;
  const Clock::time_point t0 = Clock::now();
  try {
    PhotonMapsOptions mo = settings.Resolved(scene->description).MapsOptions();
    mo.tracing.map_seed = task.map_seed();
    mo.tracing.threads = options_.threads;
    if (options_.faults) options_.faults->At("trace", ctx);
    const PhotonChunk chunk =
        TracePhotonChunk(scene->accel, scene->lights, mo, piece.photon_begin(), piece.photon_end());
    // Tracing only; a piece is not balanced here. Building costs about as much again (§2.3), which
    // the cost model's rate includes when it is measured from whole maps.
    maps_.ObserveTracing(piece.photon_end() - piece.photon_begin(), 2.0 * SecondsSince(t0));
    bytes = SerializePhotonChunk(chunk);
  } catch (const InputError& e) {
    Fail(task, ctx, e.what(), false);
    return Outcome::kDone;
  } catch (const std::exception& e) {
    Fail(task, ctx, e.what(), true);
    return Outcome::kDone;
  }
  const double trace_s = SecondsSince(t0);
  if (keeper.lost()) return Abandon(ctx, "the piece lease is gone; not uploaded");
  if (options_.faults) options_.faults->At("upload", ctx);
  SetState(State::kReporting, ctx);
  const Clock::time_point t1 = Clock::now();
  const CoordinatorClient::Upload upload = client_.UploadPhotonChunk(task.lease_id(), std::move(bytes));
  keeper.Stop();
  if (!upload.status.ok()) {
    if (IsConnectionError(upload.status)) {
      spdlog::warn("UploadPhotonChunk {}: {}; the lease will expire", ctx, StatusToString(upload.status));
      return Outcome::kConnectionLost;
    }
    Fail(task, ctx, "upload refused: " + StatusToString(upload.status), true);
    return Outcome::kDone;
  }
  spdlog::info("uploaded-piece {} accepted={} bytes={} trace_s={:.3f} upload_s={:.3f}", ctx,
               upload.accepted ? "true" : "false", upload.bytes, trace_s, SecondsSince(t1));
  std::lock_guard lock(mutex_);
  ++counters_.chunks_traced;
  return Outcome::kDone;
}

Worker::Outcome Worker::End(const v1::Task& task, const std::string& ctx, const TaskEnd& end) {
  if (end.unreachable) return Outcome::kConnectionLost;  // the step logged it; the lease will expire
  Fail(task, ctx, end.reason, end.retryable);
  return Outcome::kDone;
}

void Worker::Fail(const v1::Task& task, const std::string& ctx, const std::string& reason, bool retryable) {
  spdlog::error("failed {} retryable={}: {}", ctx, retryable ? "true" : "false", reason);
  {
    std::lock_guard lock(mutex_);
    ++counters_.failed;
  }
  client_.FailTask(task.lease_id(), ctx, reason, retryable);
}

Worker::Outcome Worker::Abandon(const std::string& ctx, const char* why) {
  spdlog::warn("abandoned {}: {}", ctx, why);
  std::lock_guard lock(mutex_);
  ++counters_.abandoned;
  return Outcome::kDone;
}

}  // namespace pf::worker
