#include "server/coordinator.h"

#include "server/http/status_page.h"
#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/referee.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>
#include <grpcpp/server.h>
#include <grpcpp/server_builder.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <mutex>

#include "common/core/error.h"
#include "photonfarm_version.h"
#include "proto/limits.h"
#include "rpc/grpc_channel.h"
#include "server/executor.h"
#include "server/rpc/auth.h"
#include "server/rpc/coordinator_operations.h"
#include "server/rpc/render_service.h"
#include "server/rpc/watch_hub.h"
#include "server/rpc/worker_gate.h"
#include "server/rpc/worker_service.h"
#include "server/scheduling/scheduler.h"
#include "server/store/data_quota.h"
#include "server/store/persister.h"
#include "server/store/scene_store.h"
#include "server/store/sqlite_store.h"

namespace pf::server {
namespace fs = std::filesystem;

namespace {

int LockDataDir(const fs::path& dir) {
  const fs::path file = dir / "LOCK";
  const int fd = ::open(file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw SystemError(file.string() + ": cannot open the lock file");
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(fd);
    throw SystemError(dir.string() + ": data directory in use by another coordinator (" + file.string() +
                      " is locked)");
  }
  return fd;
}

}  // namespace

Coordinator::Coordinator(CoordinatorOptions options) : options_(std::move(options)) {
  if (options_.clock) {
    clock_ = options_.clock;
  } else {
    own_clock_ = std::make_unique<SystemClock>();
    clock_ = own_clock_.get();
  }
  std::error_code ec;
  fs::create_directories(options_.data_dir, ec);
  if (ec)
    throw SystemError(options_.data_dir.string() + ": cannot create the data directory: " + ec.message());
  lock_fd_ = LockDataDir(options_.data_dir);

  db_ = std::make_unique<SqliteStore>(options_.data_dir / "coordinator.db");
  scenes_ = std::make_unique<SceneStore>(options_.data_dir / "scenes", *db_, *clock_);
  scenes_->LoadIndex();
  SchedulerOptions so;
  so.lease_seconds = options_.lease_seconds;
  so.max_attempts = options_.max_attempts;
  so.blocklist_failures = options_.blocklist_failures;
  so.quarantine_jobs = options_.quarantine_jobs;
  so.quarantine_seconds = options_.quarantine_seconds;
  so.build = PF_VERSION;
  const bool verify = !options_.allow_mixed_versions;  // bit-for-bit comparison needs one build
  if (!verify &&
      (options_.verify_fraction > 0 || options_.verify_piece_fraction > 0 || options_.verify_outliers))
    spdlog::warn(
        "--allow-mixed-versions: result verification is off (two builds may render a task differently, "
        "and an honest worker would be convicted; docs/farm.md, Result verification)");
  so.verification.fraction = verify ? options_.verify_fraction : 0;
  so.verification.outliers = verify && options_.verify_outliers;
  scheduler_ = std::make_unique<Scheduler>(*clock_, so);
  DistributedMapsOptions mo;
  mo.dir = options_.data_dir / "maps";
  mo.max_attempts = options_.max_attempts;
  mo.build_threads = options_.map_build_threads;
  mo.chunk_photons = options_.map_chunk_photons;
  mo.verify_fraction = verify ? options_.verify_piece_fraction : 0;
  mo.convict = verify;
  mo.quota_bytes = options_.maps_quota_bytes;
  maps_ = std::make_unique<DistributedMaps>(
      mo, *clock_, [s = scenes_.get()](const std::string& hash) { return s->DirectoryOf(hash); });
  maps_->SetScheduler(scheduler_.get());
  scheduler_->SetMapTracingHook(maps_.get());
  referee_ = std::make_unique<Referee>(*scenes_, options_.referee_threads);
  referee_->SetScheduler(scheduler_.get());
  scheduler_->SetReferee(referee_.get());
  persister_ = std::make_unique<Persister>(*scheduler_, *db_, options_.data_dir / "checkpoints", *clock_,
                                           options_.checkpoint_interval_seconds,
                                           options_.files ? *options_.files : SystemFiles());
  executor_ = std::make_unique<Executor>(options_.executor_threads);
  watches_ = std::make_unique<WatchHub>(*scheduler_, *executor_, *clock_, options_.budgets);
  admission_ = std::make_unique<Admission>(options_.budgets, *scheduler_, *scenes_);
  // Refused workers are listed in pf workers and the web page, per address (auth.h); logged once
  // per address (or id, where the address is not known) and reason, and at most once a second (a
  // flood of refused calls must not fill the log).
  struct RefusalLog {
    std::mutex mu;
    double last = -1e9;
    uint64_t unlogged = 0;
  };
  const OnWorkerRefused on_worker_refused =
      [&activity = scheduler_->activity(), &clock = *clock_, log = std::make_shared<RefusalLog>()](
          const std::string& address, const std::string& announced_id, const grpc::Status& status) {
        const std::string reason =
            StatusCodeName(status.error_code()) + std::string(": ") + status.error_message();
        if (!activity.WorkerRefused(address, announced_id, reason)) return;
        std::lock_guard lock(log->mu);
        if (clock.Now() - log->last < 1.0) {
          ++log->unlogged;
          return;
        }
        log->last = clock.Now();
        spdlog::warn("worker {}{} refused: {} (further refusals are counted in pf workers{})",
                     limits::Quote(announced_id.empty() ? "(no worker id)" : announced_id),
                     address.empty() ? "" : " at " + limits::Quote(address), reason,
                     log->unlogged == 0 ? "" : fmt::format("; {} other refusals not logged", log->unlogged));
        log->unlogged = 0;
      };
  const RoleTokens tokens{options_.client_token, options_.worker_token};
  const bool worker_needs_certificate = !options_.tls_client_ca_pem.empty();
  auth_ = std::make_shared<RoleAuthProcessor>(tokens, worker_needs_certificate, on_worker_refused);
  worker_gate_ = std::make_unique<WorkerGate>(tokens, worker_needs_certificate, on_worker_refused);
  scheduler_->SetPersistListener([p = persister_.get()] { p->Wake(); });
  scheduler_->SetChangeListener([this, w = watches_.get()](const std::string& job_id) {
    w->Notify(job_id);
    data_changed_ = true;  // a merge or a state change: files may have grown (--data-quota)
  });

  // Events and worker statistics as the last life stored them (docs/farm.md "Activity across
  // restarts"); without them `pf events` and `pf workers` start empty, nothing else changes.
  try {
    const ActivityRecords stored = db_->LoadActivity();
    scheduler_->activity().Restore(stored);
    if (!stored.empty())
      spdlog::info("activity restored: {} task events, {} workers", stored.events.size(),
                   stored.workers.size());
  } catch (const std::exception& e) {
    spdlog::error(
        "activity: the stored events and worker statistics could not be read ({}); starting without",
        e.what());
  }
  recovery_ = RecoverJobs(*db_, *scenes_, options_.data_dir / "checkpoints", *scheduler_, *clock_,
                          /*keep_other_builds=*/options_.allow_mixed_versions);
  if (recovery_.jobs_resumed + recovery_.jobs_finished + recovery_.jobs_failed > 0)
    spdlog::info(
        "recovered {} unfinished jobs ({} tasks merged from checkpoints, {} re-queued; re-run from zero: {} "
        "of "
        "another plan expansion, {} of another build), {} finished, {} could not be resumed",
        recovery_.jobs_resumed, recovery_.tasks_merged, recovery_.tasks_requeued, recovery_.jobs_reexpanded,
        recovery_.jobs_other_build, recovery_.jobs_finished, recovery_.jobs_failed);
  if (recovery_.acknowledged_lost + recovery_.jobs_rerendered + recovery_.images_lost > 0)
    spdlog::error(
        "DATA LOSS at start-up (see the lines above): {} acknowledged results lost (re-run), {} finished "
        "jobs "
        "rendered again from zero, {} images of failed or cancelled jobs lost",
        recovery_.acknowledged_lost, recovery_.jobs_rerendered, recovery_.images_lost);
  persister_->Start();
  // The map store's quota at start-up, once the jobs are known (the maps live jobs use stay).
  maps_->EnforceQuotaNow();

  operations_ = std::make_unique<CoordinatorOperations>(
      CoordinatorParts{.scheduler = *scheduler_,
                       .scenes = *scenes_,
                       .db = *db_,
                       .persister = *persister_,
                       .executor = *executor_,
                       .admission = *admission_,
                       .clock = *clock_,
                       .maps = *maps_,
                       .build_version = PF_VERSION,
                       .allow_mixed_versions = options_.allow_mixed_versions});
  render_service_ = std::make_unique<RenderServiceImpl>(*operations_, *watches_);
  worker_service_ = std::make_unique<WorkerServiceImpl>(*operations_, *worker_gate_);
}

Coordinator::~Coordinator() {
  try {
    Shutdown();
  } catch (const std::exception& e) {
    spdlog::error("shutdown: {}", e.what());
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

int Coordinator::Start() {
  CheckHttpTransport();  // before anything listens
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(options_.listen, ServerCredentials(), &port_);
  builder.SetMaxReceiveMessageSize(kMaxReceiveMessageBytes);
  builder.SetMaxSendMessageSize(kMaxSendMessageBytes);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 20000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 10000);
  builder.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 5000);
  builder.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
  // gRPC binds with SO_REUSEPORT by default: a second coordinator on a port in use would start and
  // the kernel would split the connections between the two (each with its own jobs and data dir).
  // Without it, the second one fails to listen.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.RegisterService(render_service_.get());
  builder.RegisterService(worker_service_.get());
  server_ = builder.BuildAndStart();
  if (!server_ || port_ == 0) throw SystemError("cannot listen on " + options_.listen);
  if (auto* health = server_->GetHealthCheckService()) {
    health->SetServingStatus(true);
    health->SetServingStatus("photonfarm.v1.RenderService", true);
    health->SetServingStatus("photonfarm.v1.WorkerService", true);
  }
  tick_thread_ = std::thread([this] { TickLoop(); });
  if (!options_.http_listen.empty()) {
    http_ = std::make_unique<StatusHttpServer>(
        *scheduler_, RoleTokens{options_.client_token, options_.worker_token}, options_.tls_cert_pem,
        options_.tls_key_pem, operations_.get());
    http_port_ = http_->Start(options_.http_listen);
  }
  spdlog::info(
      "serving on {} (port {}), data dir {}, lease {} s, max attempts {} (distinct workers), "
      "blocklist after {} failed attempts in a job, quarantine {} s after {} blocklists, "
      "checkpoints {}, {}, client token {}, worker token {}",
      options_.listen, port_, options_.data_dir.string(), options_.lease_seconds, options_.max_attempts,
      options_.blocklist_failures, options_.quarantine_seconds, options_.quarantine_jobs,
      options_.checkpoint_interval_seconds > 0
          ? "every " + std::to_string(int(options_.checkpoint_interval_seconds * 1000)) + " ms"
          : std::string("per merge (durable acks)"),
      options_.tls_cert_pem.empty()        ? "plaintext"
      : options_.tls_client_ca_pem.empty() ? "TLS"
                                           : "TLS + client certificates for workers",
      options_.client_token.empty() ? "off" : "required", options_.worker_token.empty() ? "off" : "required");
  spdlog::info("budgets: {}", DescribeBudgets(options_.budgets));
  spdlog::info("map store: {}", options_.maps_quota_bytes == 0
                                    ? std::string("no quota")
                                    : "quota " + std::to_string(options_.maps_quota_bytes) + " bytes");
  if (options_.data_quota_bytes > 0) spdlog::info("data dir: quota {} bytes", options_.data_quota_bytes);
  if (options_.retain_finished_seconds > 0)
    spdlog::info("finished jobs retained {} s", options_.retain_finished_seconds);
  if (!options_.allow_mixed_versions)
    spdlog::info(
        "result verification: {:.3g} of merged results re-rendered by another worker{}, {:.3g} of map pieces "
        "traced again in full; referee renders on {} thread(s)",
        options_.verify_fraction, options_.verify_outliers ? " (and every outlier)" : "",
        options_.verify_piece_fraction, options_.referee_threads);
  return port_;
}

std::shared_ptr<grpc::ServerCredentials> Coordinator::ServerCredentials() const {
  if ((options_.tls_cert_pem.empty()) != (options_.tls_key_pem.empty()))
    throw InputError("--tls-cert and --tls-key go together");
  if (options_.tls_cert_pem.empty() && !options_.tls_client_ca_pem.empty())
    throw InputError("--tls-client-ca needs --tls-cert/--tls-key");
  std::shared_ptr<grpc::ServerCredentials> credentials;
  if (!options_.tls_cert_pem.empty()) {
    grpc::SslServerCredentialsOptions ssl(options_.tls_client_ca_pem.empty()
                                              ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                              : GRPC_SSL_REQUEST_CLIENT_CERTIFICATE_AND_VERIFY);
    ssl.pem_root_certs = options_.tls_client_ca_pem;
    ssl.pem_key_cert_pairs.push_back({options_.tls_key_pem, options_.tls_cert_pem});
    credentials = grpc::SslServerCredentials(ssl);
  } else if (IsLoopbackAddress(options_.listen)) {
    // Plaintext, but only for peers on this machine; unlike InsecureServerCredentials these
    // credentials carry the auth processor.
    credentials = grpc::experimental::LocalServerCredentials(LOCAL_TCP);
  } else if (!options_.insecure) {
    throw InputError(
        "refusing to serve on the non-loopback address " + options_.listen +
        " without TLS: pass --tls-cert/--tls-key (and --tls-client-ca for workers), or --insecure "
        "for a trusted network");
  } else if (options_.client_token.size() + options_.worker_token.size() > 0) {
    throw InputError("--insecure on " + options_.listen +
                     " with tokens: bearer tokens would cross the network readable; use TLS");
  } else {
    spdlog::warn("serving plaintext without authentication on {} (--insecure)", options_.listen);
    return grpc::InsecureServerCredentials();
  }
  credentials->SetAuthMetadataProcessor(auth_);
  return credentials;
}

// The status page follows the gRPC port's rule (ServerCredentials above): with the coordinator's
// certificate it is HTTPS with that certificate (StatusHttpServer); without one, plaintext only on
// loopback, elsewhere only with --insecure and never with a client token, which is the page's
// Basic password (docs/security.md, "The web status page").
void Coordinator::CheckHttpTransport() const {
  if (options_.http_listen.empty() || !options_.tls_cert_pem.empty()) return;
  if (IsLoopbackHost(ParseHttpListen(options_.http_listen).first)) return;
  if (!options_.insecure)
    throw InputError("refusing to serve the status page (--http " + options_.http_listen +
                     ") on a non-loopback address without TLS: pass --tls-cert/--tls-key (the page is then "
                     "HTTPS with that certificate), or --insecure for a trusted network");
  if (!options_.client_token.empty())
    throw InputError("--insecure with --http " + options_.http_listen +
                     " and a client token: the token (the page's password) would cross the network readable; "
                     "use TLS");
  spdlog::warn("serving the status page plaintext without authentication on {} (--insecure)",
               options_.http_listen);
}

bool Coordinator::http_tls() const {
  return http_ && http_->tls();
}

bool IsLoopbackHost(const std::string& host) {
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0;
}

bool IsLoopbackAddress(const std::string& listen) {
  std::string host = listen;
  if (host.rfind("ipv4:", 0) == 0) host = host.substr(5);
  if (host.rfind("ipv6:", 0) == 0) host = host.substr(5);
  if (!host.empty() && host.front() == '[') {
    const size_t close = host.find(']');
    host = close == std::string::npos ? host : host.substr(1, close - 1);
  } else if (const size_t colon = host.rfind(':'); colon != std::string::npos) {
    host = host.substr(0, colon);
  }
  return IsLoopbackHost(host);
}

void Coordinator::TickLoop() {
  std::unique_lock lock(mu_);
  while (!stopping_) {
    lock.unlock();
    try {
      scheduler_->Tick();
      watches_->Tick();
      MaybeApplyRetention();
      MaybeApplyDataQuota();
      // On the executor: a transaction with its fsync, which the lease expiry here must not wait for.
      if (clock_->Now() >= next_activity_persist_ && !activity_running_.exchange(true)) {
        next_activity_persist_ = clock_->Now() + 1.0;
        if (!executor_->Post([this] {
              PersistActivity();
              activity_running_ = false;
            }))
          activity_running_ = false;  // busy: next time
      }
    } catch (const std::exception& e) {
      spdlog::error("tick: {}", e.what());
    }
    lock.lock();
    cv_.wait_for(lock, std::chrono::duration<double>(options_.tick_seconds), [&] { return stopping_; });
  }
}

void Coordinator::PersistActivity() {
  ActivityRecords changes = scheduler_->activity().TakeChanges();
  if (changes.empty()) return;
  try {
    db_->SaveActivity(changes, kMaxEventsPerJob);
    if (std::exchange(activity_storage_failing_, false)) spdlog::info("activity: stored again");
  } catch (const std::exception& e) {
    if (!std::exchange(activity_storage_failing_, true))
      spdlog::warn("activity: task events and worker statistics not stored ({}); kept in memory, retried",
                   e.what());
    scheduler_->activity().ReturnChanges(std::move(changes));
  }
}

void Coordinator::MaybeApplyRetention() {
  const double retain = options_.retain_finished_seconds;
  if (retain <= 0 || clock_->Now() < next_retention_ || retention_running_.exchange(true)) return;
  next_retention_ = clock_->Now() + std::min(kRetentionCheckSeconds, std::max(0.1, retain / 10));
  const int64_t cutoff_ms = clock_->UnixMillis() - int64_t(retain * 1000.0);
  const bool posted = executor_->Post([this, cutoff_ms] {
    try {
      operations_->DeleteFinishedBefore(cutoff_ms);
    } catch (const std::exception& e) {
      spdlog::error("retention: {}", e.what());
    }
    retention_running_ = false;
  });
  if (!posted) retention_running_ = false;  // busy: next time
}

void Coordinator::MaybeApplyDataQuota() {
  const uint64_t quota = options_.data_quota_bytes;
  const double now = clock_->Now();
  // Measured soon after the jobs change (a finished job's final files appear at its last change),
  // and now and then regardless.
  if (quota == 0 || now < next_quota_check_ ||
      (!data_changed_ && now < last_quota_check_ + kRetentionCheckSeconds) || quota_running_.exchange(true))
    return;
  next_quota_check_ = now + kDataQuotaCheckSeconds;
  last_quota_check_ = now;
  data_changed_ = false;
  const bool posted = executor_->Post([this, quota] {
    try {
      const auto t0 = std::chrono::steady_clock::now();
      const uint64_t bytes = DirectoryBytes(options_.data_dir);
      const double walk = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      next_quota_check_ = std::max(next_quota_check_.load(), clock_->Now() + 10 * walk);
      if (bytes > uint64_t(double(quota) * kDataQuotaHighWater)) {
        const auto deleted =
            operations_->DeleteFinishedOverQuota(bytes, uint64_t(double(quota) * kDataQuotaLowWater));
        const uint64_t after = deleted.jobs == 0 ? bytes : DirectoryBytes(options_.data_dir);
        if (deleted.jobs > 0)
          spdlog::info(
              "--data-quota: {} finished jobs deleted ({} bytes freed); the data dir holds {} of {} bytes",
              deleted.jobs, deleted.bytes_freed, after, quota);
        if (after > quota && !quota_warned_)
          spdlog::warn(
              "--data-quota: the data dir holds {} bytes, more than the quota of {}, and no finished job "
              "is left to delete (queued, running and paused jobs are kept)",
              after, quota);
        quota_warned_ = after > quota;
      } else {
        quota_warned_ = false;
      }
    } catch (const std::exception& e) {
      spdlog::error("--data-quota: {}", e.what());
    }
    quota_running_ = false;
  });
  if (!posted) quota_running_ = false;  // busy: next time
}

void Coordinator::Shutdown() {
  Stop(/*graceful=*/true);
}
void Coordinator::SimulateCrash() {
  Stop(/*graceful=*/false);
}

void Coordinator::Stop(bool graceful) {
  {
    std::lock_guard lock(mu_);
    if (stopping_) return;
    stopping_ = true;
  }
  cv_.notify_all();
  if (graceful) spdlog::info("shutting down");
  if (server_)
    if (auto* health = server_->GetHealthCheckService()) health->SetServingStatus(false);
  if (http_) http_->Stop();
  scheduler_->Shutdown();
  watches_->Shutdown();
  if (!graceful) persister_->Abandon();
  if (server_) {
    const double grace = graceful ? options_.shutdown_grace_seconds : 0.0;
    server_->Shutdown(std::chrono::system_clock::now() +
                      std::chrono::duration_cast<std::chrono::system_clock::duration>(
                          std::chrono::duration<double>(grace)));
  }
  if (tick_thread_.joinable()) tick_thread_.join();
  referee_->Stop();
  maps_->Stop();
  executor_->Stop();
  // The rest of the activity, the referee's and the executor's last events included.
  if (graceful) PersistActivity();
  const bool flushed = graceful && persister_->Stop();
  if (server_) server_->Wait();
  {
    std::lock_guard lock(mu_);
    stopped_ = true;
    stored_everything_ = flushed;
  }
  cv_.notify_all();
  if (graceful) spdlog::info("stopped");
}

void Coordinator::Wait() {
  std::unique_lock lock(mu_);
  cv_.wait(lock, [&] { return stopped_; });
}

bool Coordinator::StoredEverything() {
  std::lock_guard lock(mu_);
  return stored_everything_;
}

}  // namespace pf::server
