#include "worker/worker.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <thread>

#include "common/core/error.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "rpc/grpc_channel.h"
#include "rpc/tls_diagnosis.h"

namespace pf::worker {
namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

const char* StateName(State s) {
  switch (s) {
    case State::kConnecting:
      return "connecting";
    case State::kBackoff:
      return "backoff";
    case State::kIdle:
      return "idle";
    case State::kFetchingScene:
      return "fetching-scene";
    case State::kBuildingMap:
      return "building-map";
    case State::kRendering:
      return "rendering";
    case State::kReporting:
      return "reporting";
    case State::kStopping:
      return "stopping";
  }
  return "?";
}

namespace {

bool IsConnectionError(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAVAILABLE ||
         s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
}

std::string TaskContext(const v1::Task& t) {
  return "job=" + t.job_id() + " task=" + std::to_string(t.task_id()) +
         " attempt=" + std::to_string(t.attempt());
}

double SecondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

// One task's render, shared by the main loop, the render thread and the heartbeat thread.
struct Worker::Execution {
  std::mutex mutex;
  std::condition_variable cv;
  bool done = false;  // the render thread finished (output or error set)
  bool stop_heartbeat = false;
  bool lease_lost = false;
  std::optional<TaskOutput> output;
  std::string error;
  bool error_retryable = true;
  std::atomic<uint64_t> progress{0};
  // Set when the result can no longer count (the lease is gone, or it was handed back): the
  // render stops within a block of pixels or a chunk of photons instead of running to the end.
  std::atomic<bool> cancel{false};
  bool cancelled = false;  // the render thread stopped because of `cancel`
  uint64_t pixels = 1;
  double lease_seconds = 30;
};

Worker::Worker(WorkerOptions options)
    : options_(std::move(options)),
      scenes_(options_.cache_dir, options_.scene_cache_capacity),
      map_disk_(options_.map_cache_dir.empty() ? options_.cache_dir / "maps" : options_.map_cache_dir,
                options_.map_cache_bytes),
      maps_(std::make_shared<PhotonMapCache>(options_.map_cache_capacity)),
      jitter_rng_(std::random_device{}()) {
  channel_ = MakeCoordinatorChannel(options_.coordinator,
                                    ChannelOptions{.token = options_.token, .tls = options_.tls});
  stub_ = v1::WorkerService::NewStub(channel_);
}

Worker::~Worker() = default;

void Worker::SetState(State s, const std::string& context) {
  const State old = state_.exchange(s);
  if (old == s) return;
  if (context.empty())
    spdlog::debug("state {} -> {}", StateName(old), StateName(s));
  else
    spdlog::debug("state {} -> {} {}", StateName(old), StateName(s), context);
}

WorkerCounters Worker::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

void Worker::RequestStop() {
  std::lock_guard lock(mutex_);
  if (stop_.load()) return;
  stop_deadline_ = Clock::now() + Seconds(options_.grace_seconds);
  stop_ = true;
  if (poll_context_) poll_context_->TryCancel();
  wake_.notify_all();
  spdlog::info("stop requested: finishing the current task within {:.0f}s grace, no new leases",
               options_.grace_seconds);
}

void Worker::RequestAbort() {
  std::lock_guard lock(mutex_);
  stop_deadline_ = Clock::now();
  stop_ = true;
  abort_ = true;
  if (poll_context_) poll_context_->TryCancel();
  wake_.notify_all();
  spdlog::info("abort requested: handing back the current lease now");
}

bool Worker::InterruptibleSleep(std::chrono::milliseconds d, bool wake_on_stop) {
  std::unique_lock lock(mutex_);
  return wake_.wait_for(lock, d, [&] { return abort_.load() || (wake_on_stop && stop_.load()); });
}

void Worker::BackoffSleep() {
  SetState(State::kBackoff);
  // Exponential backoff with "equal jitter": half fixed, half random, so that workers that lost
  // the coordinator together do not reconnect in lockstep.
  const double cap = options_.max_backoff_seconds;
  const double base = std::min(cap, 0.1 * double(1u << std::min(failures_, 16)));
  std::uniform_real_distribution<double> u(0.5, 1.0);
  const double seconds = base * u(jitter_rng_);
  ++failures_;
  InterruptibleSleep(Seconds(seconds));
}

bool Worker::WaitForConnection() {
  SetState(State::kConnecting);
  while (!stop_requested()) {
    if (channel_->WaitForConnected(std::chrono::system_clock::now() + std::chrono::milliseconds(500))) {
      if (failures_ > 0) spdlog::info("connected to coordinator {}", options_.coordinator);
      return true;
    }
    if (failures_ == 0 || failures_ % 20 == 0) {
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
  v1::LeaseTaskRequest req;
  req.set_worker_id(options_.worker_id);
  req.set_threads(uint32_t(options_.threads));
  for (uint64_t s : maps_->CachedSeeds()) req.add_cached_map_seeds(s);
  req.set_wait_seconds(options_.poll_seconds);
  req.set_worker_version(PF_VERSION);
  grpc::ClientContext ctx;
  PrepareContext(&ctx, options_.token, Seconds(options_.poll_seconds + options_.rpc_timeout_seconds));
  {
    std::lock_guard lock(mutex_);
    if (stop_.load()) {
      *status = grpc::Status::CANCELLED;
      return std::nullopt;
    }
    poll_context_ = &ctx;
  }
  v1::LeaseTaskResponse resp;
  *status = stub_->LeaseTask(&ctx, req, &resp);
  {
    std::lock_guard lock(mutex_);
    poll_context_ = nullptr;
  }
  if (!status->ok() || !resp.has_task()) return std::nullopt;
  return resp.task();
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
        failures_ = 16;
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
    failures_ = 0;
    if (!task) continue;  // no task now: poll again
    {
      std::lock_guard lock(mutex_);
      ++counters_.leased;
    }
    const Outcome outcome = RunTask(*task);
    if (outcome == Outcome::kStop) break;
    if (outcome == Outcome::kConnectionLost) BackoffSleep();
    ++reported;
    if (options_.max_tasks > 0 && reported >= options_.max_tasks) {
      spdlog::info("reached --max-tasks {}: exiting", options_.max_tasks);
      break;
    }
  }
  SetState(State::kStopping);
  const WorkerCounters c = counters();
  spdlog::info(
      "worker {} stopped: {} leased, {} completed ({} merged), {} failed, {} abandoned ({} cancelled), {} "
      "handed back",
      options_.worker_id, c.leased, c.completed, c.merged, c.failed, c.abandoned, c.cancelled, c.handed_back);
  return exit_code;
}

SceneBundle Worker::FetchBundle(const std::string& hash, const std::string& entry) {
  if (entry.empty()) throw InputError("task for scene " + hash + " without scene_entry");
  grpc::ClientContext ctx;
  PrepareContext(&ctx, options_.token, Seconds(options_.fetch_timeout_seconds));
  v1::FetchSceneRequest req;
  req.set_scene_hash(hash);
  std::unique_ptr<grpc::ClientReader<v1::SceneFile>> reader = stub_->FetchScene(&ctx, req);
  SceneBundle bundle;
  v1::SceneFile chunk;
  while (reader->Read(&chunk)) {
    if (!bundle.files.empty() && bundle.files.back().first == chunk.path())
      bundle.files.back().second += chunk.content();  // a large file continues in the next message
    else
      bundle.files.emplace_back(chunk.path(), chunk.content());
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) throw RpcError(status);
  // The stream carries files only; the entry comes with the task (Task.scene_entry, always set
  // by the coordinator from its scene store) and is part of the content hash.
  bundle.entry = entry;
  if (BundleHash(bundle) != hash)
    throw InputError("FetchScene " + hash + ": the " + std::to_string(bundle.files.size()) +
                     " files received with entry " + entry + " do not match the hash");
  return bundle;
}

// A task in four steps: parse it, get its scene, log the settings chosen for `auto`, then render
// it on a thread of its own under supervision (lease, grace period, stop requests) and report.
Worker::Outcome Worker::RunTask(const v1::Task& task) {
  if (task.has_trace_chunk()) return RunTraceChunk(task);
  const std::string ctx = TaskContext(task);
  const Clock::time_point t0 = Clock::now();
  const std::optional<ParsedTask> parsed = ParseTask(task, ctx);
  if (!parsed) return Outcome::kDone;
  spdlog::info("leased {} map={} pixels={} samples={} lease={:.1f}s", ctx, task.map_index(), parsed->pixels,
               parsed->spec.sample_end - parsed->spec.sample_begin, task.lease_seconds());
  std::shared_ptr<Execution> exec = NewExecution(parsed->pixels, task.lease_seconds());
  LeaseKeeper keeper(this, task, ctx, exec);
  std::shared_ptr<const SceneRuntime> scene;
  if (const std::optional<Outcome> ended = GetScene(task, ctx, &scene)) return *ended;
  LogAutoSettings(task, ctx, parsed->settings, *scene);
  if (task.has_map() && parsed->settings.integrator == IntegratorKind::kPhotonMap) {
    if (const std::optional<Outcome> ended = ObtainMap(task, ctx, *parsed, *scene)) return *ended;
  } else if (parsed->settings.integrator == IntegratorKind::kPhotonMap) {
    // No map named: a map fetched for another task under this cache key is not vouched for here.
    ForgetFetchedMap(
        MapCacheKey(task.scene_hash(), parsed->settings.Resolved(scene->description), parsed->spec.map_seed),
        "");
  }
  if (keeper.lost()) {  // e.g. the fetches outlasted a lease the coordinator could not extend
    spdlog::warn("abandoned {}: the lease is gone before the render started", ctx);
    std::lock_guard slock(mutex_);
    ++counters_.abandoned;
    return Outcome::kDone;
  }
  return ExecuteSupervised(task, ctx, *parsed, std::move(scene), t0, std::move(exec), keeper);
}

std::shared_ptr<Worker::Execution> Worker::NewExecution(uint64_t pixels, double lease_seconds) {
  auto exec = std::make_shared<Execution>();
  exec->pixels = std::max<uint64_t>(pixels, 1);
  exec->lease_seconds = lease_seconds > 0 ? lease_seconds : 30.0;
  return exec;
}

Worker::LeaseKeeper::LeaseKeeper(Worker* worker, const v1::Task& task, std::string ctx,
                                 std::shared_ptr<Execution> exec)
    : exec_(exec),
      thread_([worker, &task, ctx = std::move(ctx), exec] { worker->Heartbeat(task, ctx, exec); }) {}

bool Worker::LeaseKeeper::lost() const {
  std::lock_guard lock(exec_->mutex);
  return exec_->lease_lost;
}

void Worker::LeaseKeeper::Stop() {
  {
    std::lock_guard lock(exec_->mutex);
    exec_->stop_heartbeat = true;
    exec_->cv.notify_all();
  }
  if (thread_.joinable()) thread_.join();
}

// Parse first: a task we cannot even read goes straight back as a permanent failure.
std::optional<Worker::ParsedTask> Worker::ParseTask(const v1::Task& task, const std::string& ctx) {
  ParsedTask parsed;
  try {
    parsed.camera = CameraFromProto(task.camera(), "task.camera");
    parsed.settings = SettingsFromProto(task.settings(), "task.settings");
    parsed.spec = TaskSpecFromProto(task);
  } catch (const InputError& e) {
    Fail(task, ctx, e.what(), false);
    return std::nullopt;
  }
  parsed.pixels = CountPixels(parsed.spec.pixels, parsed.camera.width, parsed.camera.height);
  return parsed;
}

// Scene: memory, disk, or FetchScene. If that fails, the task ends here (failed, or left to
// expire when the coordinator is unreachable) and the outcome says how.
std::optional<Worker::Outcome> Worker::GetScene(const v1::Task& task, const std::string& ctx,
                                                std::shared_ptr<const SceneRuntime>* scene) {
  SetState(State::kFetchingScene, ctx);
  try {
    std::string source;
    *scene = scenes_.Get(
        task.scene_hash(), [&] { return FetchBundle(task.scene_hash(), task.scene_entry()); }, &source);
    if (source != "memory")
      spdlog::info("scene {} from {} for {}", task.scene_hash().substr(0, 12), source, ctx);
  } catch (const RpcError& e) {
    if (IsConnectionError(e.status())) {
      spdlog::warn("FetchScene for {}: {}; the lease will expire", ctx, StatusToString(e.status()));
      return Outcome::kConnectionLost;
    }
    Fail(task, ctx, "fetching scene " + task.scene_hash() + ": " + StatusToString(e.status()),
         e.status().error_code() != grpc::StatusCode::NOT_FOUND);
    return Outcome::kDone;
  } catch (const InputError& e) {
    Fail(task, ctx, std::string("scene ") + task.scene_hash() + ": " + e.what(), false);
    return Outcome::kDone;
  } catch (const std::exception& e) {
    Fail(task, ctx, std::string("scene ") + task.scene_hash() + ": " + e.what(), true);
    return Outcome::kDone;
  }
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

// Render on a thread of its own so that this thread can watch the lease, the grace period
// and the stop requests; a heartbeat thread extends the lease meanwhile.
Worker::Outcome Worker::ExecuteSupervised(const v1::Task& task, const std::string& ctx,
                                          const ParsedTask& parsed, std::shared_ptr<const SceneRuntime> scene,
                                          Clock::time_point t0, std::shared_ptr<Execution> exec,
                                          LeaseKeeper& keeper) {
  const std::vector<uint64_t> cached = maps_->CachedSeeds();
  const bool map_cached = parsed.settings.integrator == IntegratorKind::kPath ||
                          std::find(cached.begin(), cached.end(), parsed.spec.map_seed) != cached.end();
  SetState(map_cached ? State::kRendering : State::kBuildingMap, ctx);
  render_in_flight_ = true;
  std::thread render =
      StartRender(exec, std::move(scene), parsed, task.scene_hash(), maps_, options_.threads);

  bool abandoned_logged = false, lease_lost = false;
  if (SuperviseUntilHandBack(ctx, *exec, &abandoned_logged, &lease_lost)) {
    keeper.Stop();
    if (!lease_lost) {
      spdlog::info("handed-back {}: shutting down before the task finished", ctx);
      SendFail(task, ctx, "worker " + options_.worker_id + " shutting down", true);
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

// The render thread owns what it uses (it is detached on a hand-back and may outlive *this).
std::thread Worker::StartRender(std::shared_ptr<Execution> exec, std::shared_ptr<const SceneRuntime> scene,
                                const ParsedTask& parsed, const std::string& scene_hash,
                                std::shared_ptr<PhotonMapCache> maps, int threads) {
  return std::thread([exec, scene, camera = parsed.camera, settings = parsed.settings, spec = parsed.spec,
                      hash = scene_hash, maps, threads] {
    std::optional<TaskOutput> out;
    std::string error;
    bool retryable = true, cancelled = false;
    try {
      out = ExecuteTask(*scene, hash, camera, settings, spec, threads, maps.get(), &exec->progress,
                        &exec->cancel);
    } catch (const Cancelled&) {
      error = "cancelled";
      cancelled = true;
    } catch (const InputError& e) {
      error = e.what();
      retryable = false;
    } catch (const std::exception& e) {
      error = e.what();
    }
    std::lock_guard lock(exec->mutex);
    exec->output = std::move(out);
    exec->error = error;
    exec->error_retryable = retryable;
    exec->cancelled = cancelled;
    exec->done = true;
    exec->cv.notify_all();
  });
}

// Watches the render until it is done (false) or the task must be handed back because of a stop
// request past its grace period or an abort (true). Cancels the render once the lease is lost.
bool Worker::SuperviseUntilHandBack(const std::string& ctx, Execution& exec, bool* abandoned_logged,
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
Worker::Outcome Worker::FinishExecution(const v1::Task& task, const std::string& ctx, Execution& exec,
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
    ObserveTracing(output.photons_emitted, output.map_seconds);
  spdlog::info("rendered {} pixels={} map_cache_hit={} map_s={:.3f} render_s={:.3f} total_s={:.3f}", ctx,
               output.pixels, output.map_cache_hit, output.map_seconds, output.render_seconds,
               SecondsSince(t0));
  return Report(task, ctx, output);
}

void Worker::Heartbeat(const v1::Task& task, const std::string& ctx, std::shared_ptr<Execution> exec) {
  double lease_seconds = exec->lease_seconds;
  while (true) {
    const auto interval = Seconds(std::max(0.05, lease_seconds / 3.0));
    {
      std::unique_lock lock(exec->mutex);
      if (exec->cv.wait_for(lock, interval, [&] { return exec->stop_heartbeat || exec->done; })) return;
    }
    v1::ExtendLeaseRequest req;
    req.set_lease_id(task.lease_id());
    req.set_worker_id(options_.worker_id);  // leases are bound to their worker
    req.set_progress(std::min(1.0, double(exec->progress.load()) / double(exec->pixels)));
    v1::ExtendLeaseResponse resp;
    grpc::ClientContext cctx;
    PrepareContext(&cctx, options_.token, std::min(interval, Seconds(options_.rpc_timeout_seconds)));
    const grpc::Status status = stub_->ExtendLease(&cctx, req, &resp);
    if (status.ok() && !resp.ok()) {
      std::lock_guard lock(exec->mutex);
      exec->lease_lost = true;
      exec->cv.notify_all();
      return;
    }
    if (status.ok()) {
      if (resp.lease_seconds() > 0) lease_seconds = resp.lease_seconds();
      spdlog::trace("extended {} progress={:.2f}", ctx, req.progress());
    } else if (status.error_code() == grpc::StatusCode::NOT_FOUND ||
               status.error_code() == grpc::StatusCode::FAILED_PRECONDITION ||
               status.error_code() == grpc::StatusCode::PERMISSION_DENIED) {  // not this worker's lease
      std::lock_guard lock(exec->mutex);
      exec->lease_lost = true;
      exec->cv.notify_all();
      return;
    } else {
      spdlog::warn("ExtendLease {}: {}", ctx, StatusToString(status));
    }
  }
}

Worker::Outcome Worker::Report(const v1::Task& task, const std::string& ctx, const TaskOutput& output) {
  SetState(State::kReporting, ctx);
  v1::CompleteTaskRequest req;
  req.set_lease_id(task.lease_id());
  req.set_worker_id(options_.worker_id);
  req.set_part(task.part());  // what was rendered (TaskSpecFromProto accepted this part)
  if (options_.faults) {      // tests only: a malicious worker
    std::vector<float> sums = output.rgb_sums;
    options_.faults->OnResult(sums);
    req.mutable_rgb_sums()->Assign(sums.begin(), sums.end());
  } else {
    req.mutable_rgb_sums()->Assign(output.rgb_sums.begin(), output.rgb_sums.end());
  }
  v1::TaskStats* st = req.mutable_stats();
  st->set_photons_emitted(output.photons_emitted);
  st->set_photons_stored(output.photons_stored);
  st->set_rays(output.rays);
  st->set_map_seconds(output.map_seconds);
  st->set_render_seconds(output.render_seconds);
  st->set_map_cache_hit(output.map_cache_hit);
  const size_t bytes = req.ByteSizeLong();

  // The result is kept while the coordinator is away (it may come back with the lease).
  const Clock::time_point give_up = Clock::now() + Seconds(options_.report_retry_seconds);
  int attempts = 0;
  while (true) {
    grpc::ClientContext cctx;
    PrepareContext(&cctx, options_.token, Seconds(options_.rpc_timeout_seconds));
    v1::CompleteTaskResponse resp;
    const grpc::Status status = stub_->CompleteTask(&cctx, req, &resp);
    if (status.ok()) {
      spdlog::info("completed {} merged={} bytes={} pixels={}", ctx, resp.merged() ? "true" : "false", bytes,
                   output.pixels);
      std::lock_guard lock(mutex_);
      ++counters_.completed;
      counters_.merged += resp.merged();
      return Outcome::kDone;
    }
    if (!IsConnectionError(status)) {
      spdlog::error("completed {} merged=false rejected: {}", ctx, StatusToString(status));
      std::lock_guard lock(mutex_);
      ++counters_.completed;
      return Outcome::kDone;
    }
    ++attempts;
    bool give_up_now = Clock::now() >= give_up;
    {
      std::lock_guard lock(mutex_);
      give_up_now = give_up_now || abort_.load() || (stop_.load() && Clock::now() >= stop_deadline_);
    }
    if (give_up_now) {
      spdlog::error("dropped result of {} after {} attempts: {}", ctx, attempts, StatusToString(status));
      return stop_requested() ? Outcome::kStop : Outcome::kConnectionLost;
    }
    if (attempts == 1)
      spdlog::warn("CompleteTask {}: {}; keeping the result and retrying", ctx, StatusToString(status));
    failures_ = std::max(failures_, attempts);
    BackoffSleep();
    SetState(State::kReporting, ctx);
  }
}

void Worker::Fail(const v1::Task& task, const std::string& ctx, const std::string& reason, bool retryable) {
  spdlog::error("failed {} retryable={}: {}", ctx, retryable ? "true" : "false", reason);
  {
    std::lock_guard lock(mutex_);
    ++counters_.failed;
  }
  SendFail(task, ctx, reason, retryable);
}

void Worker::SendFail(const v1::Task& task, const std::string& ctx, const std::string& reason,
                      bool retryable) {
  v1::FailTaskRequest req;
  req.set_lease_id(task.lease_id());
  req.set_worker_id(options_.worker_id);  // only the lease's holder may fail it
  req.set_reason(reason);
  req.set_retryable(retryable);
  for (int attempt = 0; attempt < 2; ++attempt) {
    grpc::ClientContext cctx;
    PrepareContext(&cctx, options_.token, Seconds(std::min(options_.rpc_timeout_seconds, 5.0)));
    v1::FailTaskResponse resp;
    const grpc::Status status = stub_->FailTask(&cctx, req, &resp);
    if (status.ok() || !IsConnectionError(status)) {
      if (!status.ok()) spdlog::warn("FailTask {}: {}", ctx, StatusToString(status));
      return;
    }
  }
  spdlog::warn("FailTask {}: coordinator unreachable; the lease will expire", ctx);
}

}  // namespace pf::worker
