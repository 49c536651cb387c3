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
//  FetchScene    the stored bundle as SceneFile messages in path order; a file larger than
//                1 MiB arrives as consecutive messages with the same path (concatenate them).
//                The entry file's path is Task.scene_entry.

#include "photonfarm/v1/farm.grpc.pb.h"
#include "server/rpc/service_context.h"

namespace pf::server {

inline constexpr double kMaxLeaseWaitSeconds = 30;
inline constexpr size_t kSceneChunkBytes = size_t(1) << 20;

class WorkerServiceImpl final : public photonfarm::v1::WorkerService::CallbackService {
 public:
  explicit WorkerServiceImpl(ServiceContext context) : ctx_(context) {}

  grpc::ServerUnaryReactor* LeaseTask(grpc::CallbackServerContext* context,
                                      const photonfarm::v1::LeaseTaskRequest* request,
                                      photonfarm::v1::LeaseTaskResponse* response) override;
  grpc::ServerUnaryReactor* ExtendLease(grpc::CallbackServerContext* context,
                                        const photonfarm::v1::ExtendLeaseRequest* request,
                                        photonfarm::v1::ExtendLeaseResponse* response) override;
  grpc::ServerUnaryReactor* CompleteTask(grpc::CallbackServerContext* context,
                                         const photonfarm::v1::CompleteTaskRequest* request,
                                         photonfarm::v1::CompleteTaskResponse* response) override;
  grpc::ServerUnaryReactor* FailTask(grpc::CallbackServerContext* context,
                                     const photonfarm::v1::FailTaskRequest* request,
                                     photonfarm::v1::FailTaskResponse* response) override;
  grpc::ServerWriteReactor<photonfarm::v1::SceneFile>* FetchScene(
      grpc::CallbackServerContext* context, const photonfarm::v1::FetchSceneRequest* request) override;

 private:
  ServiceContext ctx_;
};

}  // namespace pf::server
