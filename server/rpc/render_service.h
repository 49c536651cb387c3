#pragma once
// photonfarm.v1.RenderService (clients) on gRPC's callback API: thin wiring. Each handler checks
// the bearer token, validates what is cheap to validate inline, and either answers at once
// (GetJob, ListJobs, CancelJob: memory only) or posts the slow part to the Executor (UploadScene
// loads the scene; SubmitJob writes the job to SQLite before answering; GetImage encodes an EXR)
// and finishes the reactor from there. Errors are mapped by status_mapping.h.

#include "photonfarm/v1/farm.grpc.pb.h"
#include "server/rpc/service_context.h"

namespace pf::server {

class RenderServiceImpl final : public photonfarm::v1::RenderService::CallbackService {
 public:
  explicit RenderServiceImpl(ServiceContext context) : ctx_(context) {}

  grpc::ServerUnaryReactor* UploadScene(grpc::CallbackServerContext* context,
                                        const photonfarm::v1::UploadSceneRequest* request,
                                        photonfarm::v1::UploadSceneResponse* response) override;
  grpc::ServerUnaryReactor* SubmitJob(grpc::CallbackServerContext* context,
                                      const photonfarm::v1::SubmitJobRequest* request,
                                      photonfarm::v1::SubmitJobResponse* response) override;
  grpc::ServerUnaryReactor* GetJob(grpc::CallbackServerContext* context,
                                   const photonfarm::v1::GetJobRequest* request,
                                   photonfarm::v1::JobStatus* response) override;
  grpc::ServerUnaryReactor* ListJobs(grpc::CallbackServerContext* context,
                                     const photonfarm::v1::ListJobsRequest* request,
                                     photonfarm::v1::ListJobsResponse* response) override;
  grpc::ServerUnaryReactor* CancelJob(grpc::CallbackServerContext* context,
                                      const photonfarm::v1::CancelJobRequest* request,
                                      photonfarm::v1::CancelJobResponse* response) override;
  grpc::ServerWriteReactor<photonfarm::v1::JobUpdate>* WatchJob(
      grpc::CallbackServerContext* context, const photonfarm::v1::WatchJobRequest* request) override;
  grpc::ServerUnaryReactor* ListWorkers(grpc::CallbackServerContext* context,
                                        const photonfarm::v1::ListWorkersRequest* request,
                                        photonfarm::v1::ListWorkersResponse* response) override;
  grpc::ServerUnaryReactor* ListJobEvents(grpc::CallbackServerContext* context,
                                          const photonfarm::v1::ListJobEventsRequest* request,
                                          photonfarm::v1::ListJobEventsResponse* response) override;
  grpc::ServerWriteReactor<photonfarm::v1::ImageChunk>* GetImage(
      grpc::CallbackServerContext* context, const photonfarm::v1::GetImageRequest* request) override;

 private:
  ServiceContext ctx_;
};

}  // namespace pf::server
