#pragma once
// What the gRPC service classes forward to: the coordinator's parts, owned by Coordinator.
// Authentication is not among them: gRPC checks it before any handler runs (server/rpc/auth.h).

#include <string>

#include "server/clock.h"
#include "server/executor.h"
#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/scheduler.h"
#include "server/store/job_store.h"
#include "server/store/persister.h"
#include "server/store/scene_store.h"

namespace pf::server {

class WatchHub;
class Admission;

struct ServiceContext {
  Scheduler& scheduler;
  SceneStore& scenes;
  JobStore& db;  // jobs and tasks (SqliteStore)
  Persister& persister;
  Executor& executor;
  WatchHub& watches;
  Admission& admission;  // per-client and global budgets (server/rpc/budgets.h)
  const Clock& clock;
  DistributedMaps& maps;  // Photon maps traced once
  // Which workers get leases: only those of `build_version` (the coordinator's PF_VERSION)
  // unless `allow_mixed_versions` (LeaseTaskRequest.worker_version, docs/farm.md "Upgrades").
  std::string build_version;
  bool allow_mixed_versions = false;
};

}  // namespace pf::server
