#pragma once
// photonfarm.v1.WorkerService (workers, pull model) on gRPC's callback API: thin wiring over the
// Scheduler.
//
//  LeaseTask     long poll: the reactor is parked in the scheduler (no thread waits) and finished
//                when a task is queued or after wait_seconds (clamped to [0, 30]); an empty
//                response means "no task now". If the caller has gone when a task arrives, the
//                lease is returned at once (no failed attempt).
//  ExtendLease   heartbeat; ok = false: the lease is gone (expired, cancelled): stop the task.
//  CompleteTask  merged = true / false (duplicate or late result, ignored). A result of the wrong
//                size or with NaN/Inf is INVALID_ARGUMENT ("rgb_sums: …") and the task is re-run.
//                With durable acknowledgements (--checkpoint-ms 0, the default) the answer waits
//                until the result is in the journal on disk (server/store/persister.h).
//  FailTask      gives a task back (retryable: re-queued up to the attempt limit).
//  LeaveFarm     a worker stopping on its own: offline, not lost, until it calls again.
//  FetchScene    the stored bundle as SceneFile messages in path order; a file larger than
//                1 MiB arrives as consecutive messages with the same path (concatenate them).
//                The entry file's path is Task.scene_entry.

#include "photonfarm/v1/farm.grpc.pb.h"
#include "server/rpc/coordinator_api.h"
#include "server/rpc/handler_macros.h"
#include "server/rpc/worker_gate.h"

namespace pf::server {

inline constexpr double kMaxLeaseWaitSeconds = 30;
inline constexpr size_t kSceneChunkBytes = size_t(1) << 20;
// Map pieces and maps travel in parts of at most this much data (docs/farm.md, "Photon maps traced once").
inline constexpr size_t kMapPartBytes = size_t(1) << 20;
// A traced piece larger than this is refused (RESOURCE_EXHAUSTED): 65536 photons are ~1.2 MB with
// every attribute (34 bytes per photon); this allows pieces of millions.
inline constexpr uint64_t kMaxPhotonChunkBytes = uint64_t(512) << 20;

class WorkerServiceImpl final : public photonfarm::v1::WorkerService::CallbackService {
 public:
  // Every handler admits its call through `gate` first (worker_gate.h).
  WorkerServiceImpl(CoordinatorApi& api, const WorkerGate& gate) : api_(api), gate_(gate) {}

  PF_UNARY_HANDLER(LeaseTask, LeaseTaskRequest, LeaseTaskResponse);
  PF_UNARY_HANDLER(ExtendLease, ExtendLeaseRequest, ExtendLeaseResponse);
  PF_UNARY_HANDLER(CompleteTask, CompleteTaskRequest, CompleteTaskResponse);
  PF_UNARY_HANDLER(FailTask, FailTaskRequest, FailTaskResponse);
  PF_STREAM_HANDLER(FetchScene, FetchSceneRequest, SceneFile);
  // Photons traced once (server/scheduling/distributed_maps.h).
  grpc::ServerReadReactor<photonfarm::v1::PhotonChunkPart>* UploadPhotonChunk(
      grpc::CallbackServerContext* context, photonfarm::v1::UploadPhotonChunkResponse* response) override;
  PF_STREAM_HANDLER(FetchMap, FetchMapRequest, MapBytes);
  PF_UNARY_HANDLER(LeaveFarm, LeaveFarmRequest, LeaveFarmResponse);

 private:
  CoordinatorApi& api_;
  const WorkerGate& gate_;
};

}  // namespace pf::server
