#pragma once
// The assembled coordinator: owns every part (store, scheduler, persister, executor, watch hub,
// the two services), builds the gRPC server and runs the tick. main.cpp is a CLI around it;
// tests run it in-process on 127.0.0.1:0 with real channels.
//
// Data directory (--data-dir):
//   coordinator.db          SQLite: scenes, jobs, tasks (server/store/sqlite_store.h)
//   checkpoints/<job>.acc   accumulator + merged task ids (server/store/checkpoint.h)
//   scenes/<hash>/          stored scene bundles (server/store/scene_store.h)
//   maps/                   built photon maps and their pieces (server/scheduling/map_store_files.h)
//   LOCK                    flock'ed while a coordinator uses the directory
//
// gRPC server settings (docs/farm.md, "Coordinator: message sizes and keepalive"):
//   max receive message  kMaxReceiveMessageBytes = 64 MiB of payload (a scene bundle, a task
//                        result of up to kMaxPixelsPerTask pixels) + 1 MiB for framing
//   max send message     kMaxSendMessageBytes = 16 MiB (images and bundles stream in ≤ 1 MiB
//                        chunks; the largest unary answer is ListJobs)
//   keepalive            pings idle clients every 20 s (10 s timeout); accepts client pings as
//                        often as every 5 s, with or without calls in flight (so a worker with
//                        keepalive ≥ 5 s notices a dead coordinator and is never sent GOAWAY)
//   health               grpc.health.v1 ("" and both services SERVING until shutdown)
//   reflection           enabled
//
// Shutdown (SIGTERM/SIGINT in main): health NOT_SERVING, no new leases, parked long polls and
// watches answered, in-flight RPCs drained (≤ 5 s), background work drained, final flush of rows
// and checkpoints (StoredEverything says whether it stored everything). Leased tasks are
// re-queued at the next start without counting an attempt.

#include <grpcpp/security/server_credentials.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "common/core/file_layer.h"
#include "proto/limits.h"
#include "server/clock.h"
#include "server/rpc/budgets.h"
#include "server/scheduling/recovery.h"

namespace grpc {
class Server;
}

namespace pf::server {

class SqliteStore;
class SceneStore;
class Scheduler;
class Persister;
class Executor;
class WatchHub;
class Admission;
class RoleAuthProcessor;
class WorkerGate;
class RenderServiceImpl;
class WorkerServiceImpl;
class CoordinatorOperations;
class StatusHttpServer;
class DistributedMaps;
class Referee;

// How often --retain-finished looks for jobs to delete (at most).
inline constexpr double kRetentionCheckSeconds = 60;

// Defaults of --verify-fraction and --verify-piece-fraction (docs/farm.md "Result verification":
// their cost is measured there).
inline constexpr double kDefaultVerifyFraction = 0.03;
inline constexpr double kDefaultVerifyPieceFraction = 0.1;

// The message sizes are in proto/limits.h with every other limit.
using limits::kMaxReceiveMessageBytes;
using limits::kMaxSendMessageBytes;

struct CoordinatorOptions {
  std::string listen = "127.0.0.1:0";
  std::filesystem::path data_dir = "pf-data";
  std::string client_token;  // RenderService bearer token; empty: open
  std::string worker_token;  // WorkerService bearer token; empty: open
  // TLS (docs/security.md): PEM server certificate chain and key; both or neither. With
  // tls_client_ca, peers may present a client certificate signed by it, and WorkerService calls
  // must (mTLS for workers).
  std::string tls_cert_pem, tls_key_pem, tls_client_ca_pem;
  // Listening on a non-loopback address in plaintext is refused unless this is set (tokens
  // would cross the network readable; docs/security.md).
  bool insecure = false;
  double lease_seconds = 30;
  uint32_t max_attempts = 3;
  // Worker health (server/scheduling/worker_health.h, docs/farm.md "Worker health").
  uint32_t blocklist_failures = 3;
  uint32_t quarantine_jobs = 3;
  double quarantine_seconds = 900;
  double checkpoint_interval_seconds = 0;  // 0: durable acknowledgements (persister.h)
  // Retention (docs/farm.md "Deleting jobs"): > 0 deletes finished jobs this long after they ended,
  // checked every kRetentionCheckSeconds (or a tenth of it, if shorter); 0 keeps them.
  double retain_finished_seconds = 0;
  double tick_seconds = 0.05;  // lease/long-poll/budget/watch timer resolution
  size_t executor_threads = 2;
  double shutdown_grace_seconds = 5;
  const Clock* clock = nullptr;  // null: the system clock
  // The system calls of the result journal and checkpoints; null: the real ones (tests inject
  // faults through it: tests/server/storage_faults_test.cpp).
  FileLayer* files = nullptr;
  // Web status page (server/http/); empty: none. HTTPS with tls_cert_pem when set; without it,
  // a non-loopback address is refused like `listen` (docs/security.md, "The web status page").
  std::string http_listen;
  // Photon maps traced once (server/scheduling/distributed_maps.h).
  int map_build_threads = 1;           // threads of one map's assembly and balance
  uint64_t map_chunk_photons = 65536;  // photons per traced piece
  // The map store's quota in bytes (pf-coordinator --maps-quota; server/scheduling/map_quota.h),
  // 0 = none: past it the least recently used maps no live job uses are evicted.
  uint64_t maps_quota_bytes = 0;
  // The data dir's quota in bytes (pf-coordinator --data-quota; server/store/data_quota.h), 0 =
  // none: past it the finished jobs that ended first are deleted.
  uint64_t data_quota_bytes = 0;
  // Lease to workers of another build too (LeaseTaskRequest.worker_version; docs/farm.md
  // "Upgrades"). Off: such a worker's LeaseTask is FAILED_PRECONDITION.
  bool allow_mixed_versions = false;
  // Per-client and global budgets (server/rpc/budgets.h; pf-coordinator --limit NAME=VALUE).
  Budgets budgets;
  // Result verification (docs/farm.md "Result verification"): the fraction of merged results
  // another worker renders again (chosen by the CSPRNG), whether results the outlier test flags
  // are verified too, the fraction of uploaded map pieces the coordinator traces again in full,
  // and the threads of the coordinator's own renders (the referee). With allow_mixed_versions all
  // of it is off: two builds may render differently, and an honest worker would be convicted.
  double verify_fraction = kDefaultVerifyFraction;
  bool verify_outliers = true;
  double verify_piece_fraction = kDefaultVerifyPieceFraction;
  int referee_threads = 1;
};

// True for 127.x.y.z, ::1 and localhost (with a port, "[::1]:50051"). Anything else, "0.0.0.0"
// included, counts as reachable from the network.
bool IsLoopbackAddress(const std::string& listen);
// The same for a host without port or brackets ("::1", "127.0.0.1", "localhost").
bool IsLoopbackHost(const std::string& host);

class Coordinator {
 public:
  // Opens (or creates) the data directory and resumes its unfinished jobs. No network yet.
  explicit Coordinator(CoordinatorOptions options);
  ~Coordinator();  // Shutdown()
  Coordinator(const Coordinator&) = delete;
  Coordinator& operator=(const Coordinator&) = delete;

  // Binds and serves; returns the bound port. SystemError if the address cannot be bound.
  int Start();
  // Graceful stop (see above). Idempotent; safe from any thread except gRPC callbacks.
  void Shutdown();
  // Tests: stop serving as a crash would leave things — no final flush of rows or checkpoints.
  void SimulateCrash();
  // Blocks until Shutdown (or SimulateCrash) has completed.
  void Wait();
  // After a stop: whether the final flush stored every merged result, checkpoint and row (false
  // after SimulateCrash). pf-coordinator exits 1 if not: what was not stored is re-run.
  bool StoredEverything();

  const RecoveryReport& recovery() const { return recovery_; }
  Scheduler& scheduler() { return *scheduler_; }
  Persister& persister() { return *persister_; }
  SceneStore& scenes() { return *scenes_; }
  DistributedMaps& maps() { return *maps_; }
  WatchHub& watches() { return *watches_; }
  int port() const { return port_; }
  int http_port() const { return http_port_; }  // 0 without --http
  bool http_tls() const;                        // the status page is HTTPS

 private:
  void Stop(bool graceful);
  void TickLoop();
  // --retain-finished: the finished jobs past it are deleted (on the executor, one run at a time).
  void MaybeApplyRetention();
  // --data-quota (server/store/data_quota.h): the same, for the data dir's size.
  void MaybeApplyDataQuota();
  // The farm's activity since the last call into the database (activity_store.h): every second
  // on the executor (posted by the tick thread, one at a time), once more at a graceful stop.
  void PersistActivity();
  std::shared_ptr<grpc::ServerCredentials> ServerCredentials() const;
  void CheckHttpTransport() const;

  CoordinatorOptions options_;
  std::unique_ptr<Clock> own_clock_;
  const Clock* clock_;
  int lock_fd_ = -1;
  std::unique_ptr<SqliteStore> db_;
  std::unique_ptr<SceneStore> scenes_;
  std::unique_ptr<Scheduler> scheduler_;
  std::unique_ptr<DistributedMaps> maps_;
  std::unique_ptr<Referee> referee_;
  std::unique_ptr<Persister> persister_;
  std::unique_ptr<Executor> executor_;
  std::unique_ptr<WatchHub> watches_;
  std::unique_ptr<Admission> admission_;
  std::shared_ptr<RoleAuthProcessor> auth_;
  std::unique_ptr<WorkerGate> worker_gate_;
  std::unique_ptr<CoordinatorOperations> operations_;  // what the handlers call (coordinator_api.h)
  std::unique_ptr<RenderServiceImpl> render_service_;
  std::unique_ptr<WorkerServiceImpl> worker_service_;
  std::unique_ptr<grpc::Server> server_;
  std::unique_ptr<StatusHttpServer> http_;
  int http_port_ = 0;
  RecoveryReport recovery_;
  int port_ = 0;

  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  bool stopped_ = false;
  bool stored_everything_ = false;
  std::thread tick_thread_;
  double next_retention_ = 0;                  // Clock::Now() of the next check (tick thread only)
  double next_activity_persist_ = 0;           // Clock::Now() of the next PersistActivity (tick thread only)
  bool activity_storage_failing_ = false;      // logged once per failure run (one PersistActivity at a time)
  std::atomic<bool> activity_running_{false};  // a PersistActivity is posted to the executor
  std::atomic<bool> retention_running_{false};
  std::atomic<double> next_quota_check_{0};  // --data-quota: as the two above
  double last_quota_check_ = 0;
  std::atomic<bool> quota_running_{false};
  std::atomic<bool> data_changed_{true};  // a job changed since the last measurement
  bool quota_warned_ = false;  // a quota only live jobs exceed was warned about (executor task only)
};

}  // namespace pf::server
