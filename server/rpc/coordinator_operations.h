#pragma once
// The coordinator's operations behind the RPC handlers (coordinator_api.h): the one place that
// knows which of the coordinator's parts an operation uses — the scheduler, the scene store, the
// job store, the persister, the photon maps, the budgets — and in what order. Owned by
// Coordinator (server/coordinator.h), which owns the parts.

#include <string>

#include "server/clock.h"
#include "server/rpc/coordinator_api.h"
#include "server/store/job_store.h"
#include "server/store/persister.h"

namespace pf::server {

struct CoordinatorParts {
  Scheduler& scheduler;
  SceneStore& scenes;
  JobStore& db;  // jobs and tasks (SqliteStore)
  Persister& persister;
  Executor& executor;
  Admission& admission;  // per-client and global budgets (server/rpc/budgets.h)
  const Clock& clock;
  DistributedMaps& maps;  // Photon maps traced once
  // Which workers get leases: only those of `build_version` (the coordinator's PF_VERSION)
  // unless `allow_mixed_versions` (LeaseTaskRequest.worker_version, docs/farm.md "Upgrades").
  std::string build_version;
  bool allow_mixed_versions = false;
};

class CoordinatorOperations final : public CoordinatorApi {
 public:
  explicit CoordinatorOperations(CoordinatorParts parts) : p_(std::move(parts)) {}

  Executor& executor() override { return p_.executor; }

  Reservation AdmitSceneUpload(const std::string& client, uint64_t bytes) override;
  UploadResult StoreScene(const SceneBundle& bundle, const Reservation& upload) override;
  AdmittedJob AdmitJob(const photonfarm::v1::JobSpec& spec, const std::string& client) override;
  std::string SubmitJob(AdmittedJob job) override;
  photonfarm::v1::JobStatus JobStatus(const std::string& job_id) override;
  Scheduler::JobPage ListJobs(bool include_finished, uint64_t after_seq, size_t limit) override;
  photonfarm::v1::JobStatus CancelJob(const std::string& job_id) override;
  photonfarm::v1::JobStatus SetJobPaused(const std::string& job_id, bool paused) override;
  photonfarm::v1::DeleteJobResponse DeleteJob(const std::string& job_id) override;
  AdmittedRequeue AdmitRequeue(const photonfarm::v1::RequeueJobRequest& request,
                               const std::string& client) override;
  photonfarm::v1::RequeueJobResponse RequeueJob(AdmittedRequeue requeue) override;
  // --retain-finished (docs/farm.md "Deleting jobs"): deletes every finished job that ended before
  // `cutoff_unix_ms`, as DeleteJob does; one that cannot be deleted now is logged and left for the
  // next run. Returns how many were deleted.
  size_t DeleteFinishedBefore(int64_t cutoff_unix_ms);
  // --data-quota (server/store/data_quota.h): while `bytes` (what the data dir holds) less what
  // was freed exceeds `target`, deletes the finished job that ended first, as DeleteJob does.
  struct QuotaDeletion {
    size_t jobs = 0;
    uint64_t bytes_freed = 0;
  };
  QuotaDeletion DeleteFinishedOverQuota(uint64_t bytes, uint64_t target);
  std::vector<photonfarm::v1::WorkerInfo> Workers() override;
  std::vector<photonfarm::v1::TaskEvent> JobEvents(const std::string& job_id, uint64_t* dropped) override;
  ResolvedImage JobImage(const std::string& job_id, photonfarm::v1::JobStatus* status) override;

  std::optional<std::string> WorkerSeen(const WorkerHello& hello) override;
  uint64_t LeaseOrWait(const LeaseRequest& request, double wait_seconds,
                       std::function<void(std::optional<Lease>)> done) override;
  void CancelWait(uint64_t waiter) override;
  void ReturnLease(const std::string& lease_id) override;
  void WorkerLeft(const std::string& worker_id) override;
  std::optional<BuiltMap> MapFor(const std::string& job_id, uint64_t map_index) override;
  ExtendResult ExtendLease(const std::string& lease_id, const std::string& worker_id,
                           double progress) override;
  CompleteResult CompleteTask(const std::string& lease_id, const std::string& worker_id,
                              std::span<const float> rgb_sums, RadiancePart part,
                              const TaskStats& stats) override;
  void AcknowledgeWhenStored(const CompleteResult& merged, std::span<const float> rgb_sums,
                             std::function<void(const std::string& not_stored)> answer) override;
  FailOutcome FailTask(const std::string& lease_id, const std::string& worker_id, const std::string& reason,
                       bool retryable) override;
  std::vector<std::pair<std::string, std::filesystem::path>> SceneFiles(
      const std::string& scene_hash) override;
  DistributedMaps::UploadAdmission BeginPieceUpload(const std::string& lease_id,
                                                    const std::string& worker_id) override;
  void EndPieceUpload(const std::string& lease_id) override;
  DistributedMaps::Accepted AcceptPiece(const std::string& lease_id, const std::string& worker_id,
                                        const std::string& bytes) override;
  BuiltMapFile MapFile(const std::string& map_key) override;

 private:
  // Validation and budgets of a spec, whoever wrote it (AdmitJob: a client; AdmitRequeue: RequeuedSpec).
  AdmittedJob AdmitSpec(const photonfarm::v1::JobSpec& spec, const std::string& client);
  CoordinatorParts p_;
};

}  // namespace pf::server
