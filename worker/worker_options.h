#pragma once
// What a pf-worker is told on its command line (worker_main.cpp), shared by the pull loop
// (worker.h), its coordinator client and its scene and map obtainers.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

#include "rpc/grpc_channel.h"
#include "worker/worker_faults.h"

namespace pf::worker {

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

}  // namespace pf::worker
