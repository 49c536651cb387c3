#pragma once
// photonfarm.v1.RenderService (clients) on gRPC's callback API: thin wiring. Each handler checks
// the bearer token, validates what is cheap to validate inline, and either answers at once
// (GetJob, ListJobs, CancelJob: memory only) or posts the slow part to the Executor (UploadScene
// loads the scene; SubmitJob writes the job to SQLite before answering; GetImage encodes an EXR)
// and finishes the reactor from there. Errors are mapped by status_mapping.h.

#include "photonfarm/v1/farm.grpc.pb.h"
#include "server/rpc/handler_macros.h"
#include "server/rpc/service_context.h"

namespace pf::server {

class RenderServiceImpl final : public photonfarm::v1::RenderService::CallbackService {
 public:
  explicit RenderServiceImpl(ServiceContext context) : ctx_(context) {}

  PF_UNARY_HANDLER(UploadScene, UploadSceneRequest, UploadSceneResponse);
  PF_UNARY_HANDLER(SubmitJob, SubmitJobRequest, SubmitJobResponse);
  PF_UNARY_HANDLER(GetJob, GetJobRequest, JobStatus);
  PF_UNARY_HANDLER(ListJobs, ListJobsRequest, ListJobsResponse);
  PF_UNARY_HANDLER(CancelJob, CancelJobRequest, CancelJobResponse);
  PF_STREAM_HANDLER(WatchJob, WatchJobRequest, JobUpdate);
  PF_UNARY_HANDLER(ListWorkers, ListWorkersRequest, ListWorkersResponse);
  PF_UNARY_HANDLER(ListJobEvents, ListJobEventsRequest, ListJobEventsResponse);
  PF_STREAM_HANDLER(GetImage, GetImageRequest, ImageChunk);

 private:
  ServiceContext ctx_;
};

}  // namespace pf::server
