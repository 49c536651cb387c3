#pragma once
// photonfarm.v1.RenderService (clients) on gRPC's callback API: thin wiring. Each handler checks
// the bearer token, validates what is cheap to validate inline, and either answers at once
// (GetJob, ListJobs, CancelJob: memory only) or posts the slow part to the Executor (UploadScene
// loads the scene; SubmitJob writes the job to SQLite before answering; GetImage encodes an EXR)
// and finishes the reactor from there. Errors are mapped by status_mapping.h.

#include "photonfarm/v1/farm.grpc.pb.h"
#include "server/rpc/coordinator_api.h"
#include "server/rpc/handler_macros.h"

namespace pf::server {

class WatchHub;

class RenderServiceImpl final : public photonfarm::v1::RenderService::CallbackService {
 public:
  RenderServiceImpl(CoordinatorApi& api, WatchHub& watches) : api_(api), watches_(watches) {}

  PF_UNARY_HANDLER(UploadScene, UploadSceneRequest, UploadSceneResponse);
  PF_UNARY_HANDLER(SubmitJob, SubmitJobRequest, SubmitJobResponse);
  PF_UNARY_HANDLER(GetJob, GetJobRequest, JobStatus);
  PF_UNARY_HANDLER(ListJobs, ListJobsRequest, ListJobsResponse);
  PF_UNARY_HANDLER(CancelJob, CancelJobRequest, CancelJobResponse);
  PF_UNARY_HANDLER(PauseJob, PauseJobRequest, PauseJobResponse);
  PF_UNARY_HANDLER(ResumeJob, ResumeJobRequest, ResumeJobResponse);
  PF_UNARY_HANDLER(DeleteJob, DeleteJobRequest, DeleteJobResponse);
  PF_UNARY_HANDLER(RequeueJob, RequeueJobRequest, RequeueJobResponse);
  PF_STREAM_HANDLER(WatchJob, WatchJobRequest, JobUpdate);
  PF_UNARY_HANDLER(ListWorkers, ListWorkersRequest, ListWorkersResponse);
  PF_UNARY_HANDLER(ListJobEvents, ListJobEventsRequest, ListJobEventsResponse);
  PF_STREAM_HANDLER(GetImage, GetImageRequest, ImageChunk);

 private:
  CoordinatorApi& api_;
  WatchHub& watches_;  // WatchJob streams, fed by the scheduler (watch_hub.h)
};

}  // namespace pf::server
