#pragma once
// What the gRPC handlers call: the coordinator's operations, one interface (docs/design.md, S10). The
// handlers (render_service.cpp, worker_service.cpp) only translate — a request's fields are checked and
// turned into these calls, the outcome into a response and a status — and choose the thread: cheap calls on
// gRPC's thread, those marked "executor" on executor() (never O(pixels) or O(photons) work on an RPC thread).
// Everything behind it (which parts the coordinator has, how they are locked, what is stored when) is
// CoordinatorOperations' (coordinator_operations.h), so a handler cannot reach past it into the
// scheduler, the stores or the maps, and tests can put a fake behind the handlers.
//
// Errors are thrown as the core's and server/errors.h's types; status_mapping.h maps them to
// gRPC codes, naming the field.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/render/radiance_part.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.pb.h"
#include "server/executor.h"
#include "server/rpc/budgets.h"
#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/scheduler.h"
#include "server/store/scene_store.h"

namespace pf::server {

// A job that passed validation and the budgets, not yet in the scheduler: its reservation
// counts it against the budgets until it is submitted.
struct AdmittedJob {
  JobConfig config;
  std::string client;
  Reservation reservation;
};

// A requeue admitted (RequeueJob): the finished job it starts from and the new job, validated.
struct AdmittedRequeue {
  Scheduler::FinishedJob source;
  AdmittedJob job;
};

// A built photon map to stream to a worker: its file and the digest its trailer holds.
struct BuiltMapFile {
  std::filesystem::path file;
  std::string digest;  // hex SHA-256
};

class CoordinatorApi {
 public:
  virtual ~CoordinatorApi() = default;

  // The coordinator's threads for slow work (docs/farm.md, "Threads").
  virtual Executor& executor() = 0;

  // --- Clients (RenderService) ---
  // The budgets of an upload of `bytes`, before the request waits for a thread.
  virtual Reservation AdmitSceneUpload(const std::string& client, uint64_t bytes) = 0;
  // Executor: stores the bundle (content-addressed; an upload of a stored scene costs no bytes of
  // the budget).
  virtual UploadResult StoreScene(const SceneBundle& bundle, const Reservation& upload) = 0;
  // Validation (InputError naming the field) and the budgets, in memory: cheap.
  virtual AdmittedJob AdmitJob(const photonfarm::v1::JobSpec& spec, const std::string& client) = 0;
  // Executor: expands, stores and queues the job; its id.
  virtual std::string SubmitJob(AdmittedJob job) = 0;
  virtual photonfarm::v1::JobStatus JobStatus(const std::string& job_id) = 0;  // NotFoundError
  virtual Scheduler::JobPage ListJobs(bool include_finished, uint64_t after_seq, size_t limit) = 0;
  virtual photonfarm::v1::JobStatus CancelJob(const std::string& job_id) = 0;
  // PauseJob / ResumeJob: the flag set in memory, then stored (PreconditionError for a finished job).
  virtual photonfarm::v1::JobStatus SetJobPaused(const std::string& job_id, bool paused) = 0;
  // DeleteJob (docs/farm.md "Deleting jobs"): NotFoundError, PreconditionError for a live job.
  virtual photonfarm::v1::DeleteJobResponse DeleteJob(const std::string& job_id) = 0;
  // RequeueJob (docs/farm.md "Requeueing a job"; server/scheduling/job_requeue.h): the finished
  // job, the new spec validated and the budgets, in memory (NotFoundError, PreconditionError for
  // a live job, InputError naming the field).
  virtual AdmittedRequeue AdmitRequeue(const photonfarm::v1::RequeueJobRequest& request,
                                       const std::string& client) = 0;
  // Executor: carries the finished job's results, stores and queues the new job.
  virtual photonfarm::v1::RequeueJobResponse RequeueJob(AdmittedRequeue requeue) = 0;
  virtual std::vector<photonfarm::v1::WorkerInfo> Workers() = 0;
  // NotFoundError for an unknown job; `dropped`: events no longer kept.
  virtual std::vector<photonfarm::v1::TaskEvent> JobEvents(const std::string& job_id, uint64_t* dropped) = 0;
  // Executor: the job's merged image (and its status at that moment).
  virtual ResolvedImage JobImage(const std::string& job_id, photonfarm::v1::JobStatus* status) = 0;

  // --- Workers (WorkerService) ---
  struct WorkerHello {
    std::string worker_id, peer, version;
    uint32_t threads = 0;
  };
  // A worker asks for work: recorded as seen. A refusal (another build, docs/farm.md "Upgrades"):
  // the reason, and the worker is listed as refused.
  virtual std::optional<std::string> WorkerSeen(const WorkerHello& hello) = 0;
  // Long poll (Scheduler::LeaseOrWait): `done` runs once, maybe before this returns.
  virtual uint64_t LeaseOrWait(const LeaseRequest& request, double wait_seconds,
                               std::function<void(std::optional<Lease>)> done) = 0;
  virtual void CancelWait(uint64_t waiter) = 0;
  // A lease that never reached its worker: queued again at once.
  virtual void ReturnLease(const std::string& lease_id) = 0;
  // The worker is leaving (LeaveFarm): offline, not lost (Scheduler::WorkerLeft).
  virtual void WorkerLeft(const std::string& worker_id) = 0;
  // The built map a render task of `job_id` fetches; nullopt if its worker traces it.
  virtual std::optional<BuiltMap> MapFor(const std::string& job_id, uint64_t map_index) = 0;
  virtual ExtendResult ExtendLease(const std::string& lease_id, const std::string& worker_id,
                                   double progress) = 0;
  struct TaskStats {
    uint64_t photons_emitted = 0;
    double seconds = 0;
  };
  virtual CompleteResult CompleteTask(const std::string& lease_id, const std::string& worker_id,
                                      std::span<const float> rgb_sums, RadiancePart part,
                                      const TaskStats& stats) = 0;
  // A merged result is acknowledged only once stored (docs/farm.md "Durability", D1): `answer`
  // runs once, with "" when it is stored (at once if results are not journaled) or why not.
  virtual void AcknowledgeWhenStored(const CompleteResult& merged, std::span<const float> rgb_sums,
                                     std::function<void(const std::string& not_stored)> answer) = 0;
  virtual FailOutcome FailTask(const std::string& lease_id, const std::string& worker_id,
                               const std::string& reason, bool retryable) = 0;
  // Executor: the files of a stored scene, (bundle path, file). NotFoundError if unknown.
  virtual std::vector<std::pair<std::string, std::filesystem::path>> SceneFiles(
      const std::string& scene_hash) = 0;
  // Photon-map pieces (distributed_maps.h): an upload's admission, its end, and its bytes
  // (executor: parsed, checked and stored).
  virtual DistributedMaps::UploadAdmission BeginPieceUpload(const std::string& lease_id,
                                                            const std::string& worker_id) = 0;
  virtual void EndPieceUpload(const std::string& lease_id) = 0;
  virtual DistributedMaps::Accepted AcceptPiece(const std::string& lease_id, const std::string& worker_id,
                                                const std::string& bytes) = 0;
  // Executor: a built map's file; NotFoundError naming map_key if there is none.
  virtual BuiltMapFile MapFile(const std::string& map_key) = 0;
};

}  // namespace pf::server
