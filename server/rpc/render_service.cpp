#include "server/rpc/render_service.h"

#include "proto/limits.h"

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string_view>
#include <utility>

#include "common/core/error.h"
#include "common/scene/scene_bundle.h"
#include "server/assembly/image_snapshot.h"
#include "server/errors.h"
#include "server/rpc/buffered_stream.h"
#include "server/rpc/status_mapping.h"
#include "server/rpc/watch_hub.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

grpc::Status Busy() {
  return {grpc::StatusCode::UNAVAILABLE, "coordinator busy or shutting down; retry"};
}

// A call answered at once, on the RPC thread (the cheap reads): `body` through Guarded.
template <typename F>
grpc::ServerUnaryReactor* FinishGuarded(grpc::CallbackServerContext* context, std::string_view rpc,
                                        F&& body) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(Guarded(rpc, std::forward<F>(body)));
  return reactor;
}

// A call in two steps: `check` (validation and budgets: cheap, memory only) on the RPC thread,
// then, if it passed, `work` on the executor (expansion, SQLite, files). Each step's exception is
// the call's status (Guarded); a full or stopping executor is UNAVAILABLE (Busy).
template <typename Check, typename Work>
grpc::ServerUnaryReactor* CheckThenWork(grpc::CallbackServerContext* context, Executor& executor,
                                        std::string_view rpc, Check&& check, Work work) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  const grpc::Status valid = Guarded(rpc, [&] {
    check();
    return grpc::Status::OK;
  });
  if (!valid.ok()) {
    reactor->Finish(valid);
    return reactor;
  }
  const bool posted = executor.Post([reactor, rpc, work] {
    reactor->Finish(Guarded(rpc, [&] {
      work();
      return grpc::Status::OK;
    }));
  });
  if (!posted) reactor->Finish(Busy());
  return reactor;
}

void RequireJobId(const std::string& id) {
  limits::CheckId(id, "job_id");
}

// ListJobs cursors: "p1." + the decimal sequence number of the page's last job. Opaque to
// clients; anything else is refused without echoing it.
constexpr std::string_view kPageTokenPrefix = "p1.";

std::string PageToken(uint64_t last_seq) {
  return std::string(kPageTokenPrefix) + std::to_string(last_seq);
}

uint64_t ParsePageToken(const std::string& token) {
  if (token.empty()) return 0;
  const std::string_view digits =
      std::string_view(token).substr(std::min(token.size(), kPageTokenPrefix.size()));
  bool ok = token.size() <= limits::kMaxIdBytes && token.rfind(kPageTokenPrefix, 0) == 0 && !digits.empty() &&
            digits.size() <= 19 && digits[0] != '0';
  uint64_t seq = 0;
  for (const char c : digits) {
    if (!ok) break;
    ok = c >= '0' && c <= '9';
    seq = seq * 10 + uint64_t(c - '0');
  }
  if (!ok) throw InputError("page_token: not a next_page_token of an earlier ListJobs answer");
  return seq;
}

}  // namespace

grpc::ServerUnaryReactor* RenderServiceImpl::UploadScene(grpc::CallbackServerContext* context,
                                                         const v1::UploadSceneRequest* request,
                                                         v1::UploadSceneResponse* response) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  // The budgets before the request waits for a thread (docs/security.md "Budgets"): a queued
  // upload holds its whole message.
  auto upload = std::make_shared<Reservation>();
  const grpc::Status admitted = Guarded("UploadScene", [&] {
    uint64_t bytes = 0;
    for (const v1::SceneFile& f : request->bundle().files()) bytes += f.content().size();
    *upload = api_.AdmitSceneUpload(ClientOf(*context), bytes);
    return grpc::Status::OK;
  });
  if (!admitted.ok()) {
    reactor->Finish(admitted);
    return reactor;
  }
  // The reservation is released before the answer is sent: a client that uploads again as soon
  // as it has the answer must find its slot free (the lambda that holds it may be destroyed
  // only after the answer has left).
  const bool posted = api_.executor().Post([this, reactor, request, response, upload] {
    const grpc::Status status = Guarded("UploadScene", [&] {
      if (request->bundle().files_size() == 0)
        throw InputError("bundle.files: at least one file is required");
      SceneBundle bundle;
      bundle.entry = request->bundle().entry();
      bundle.files.reserve(size_t(request->bundle().files_size()));
      for (const v1::SceneFile& f : request->bundle().files())
        bundle.files.emplace_back(f.path(), f.content());
      const UploadResult result = api_.StoreScene(bundle, *upload);
      response->set_scene_hash(result.info.hash);
      response->set_triangles(result.info.triangles);
      response->set_lights(result.info.lights);
      for (const std::string& w : result.info.warnings) response->add_warnings(w);
      return grpc::Status::OK;
    });
    upload->Release();
    reactor->Finish(status);
  });
  if (!posted) {
    upload->Release();
    reactor->Finish(Busy());
  }
  return reactor;
}

grpc::ServerUnaryReactor* RenderServiceImpl::SubmitJob(grpc::CallbackServerContext* context,
                                                       const v1::SubmitJobRequest* request,
                                                       v1::SubmitJobResponse* response) {
  // Validation and the budgets happen before anything is expanded or stored (docs/security.md
  // "Budgets").
  auto admitted = std::make_shared<AdmittedJob>();
  return CheckThenWork(
      context, api_.executor(), "SubmitJob",
      [&] { *admitted = api_.AdmitJob(request->spec(), ClientOf(*context)); },
      [this, response, admitted] { response->set_job_id(api_.SubmitJob(std::move(*admitted))); });
}

grpc::ServerUnaryReactor* RenderServiceImpl::RequeueJob(grpc::CallbackServerContext* context,
                                                        const v1::RequeueJobRequest* request,
                                                        v1::RequeueJobResponse* response) {
  // As SubmitJob: checked and budgeted first, the checkpoint copy and the rows on the executor.
  auto admitted = std::make_shared<AdmittedRequeue>();
  return CheckThenWork(
      context, api_.executor(), "RequeueJob",
      [&] {
        RequireJobId(request->job_id());
        *admitted = api_.AdmitRequeue(*request, ClientOf(*context));
      },
      [this, response, admitted] { *response = api_.RequeueJob(std::move(*admitted)); });
}

grpc::ServerUnaryReactor* RenderServiceImpl::GetJob(grpc::CallbackServerContext* context,
                                                    const v1::GetJobRequest* request,
                                                    v1::JobStatus* response) {
  return FinishGuarded(context, "GetJob", [&] {
    RequireJobId(request->job_id());
    *response = api_.JobStatus(request->job_id());
    return grpc::Status::OK;
  });
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListJobs(grpc::CallbackServerContext* context,
                                                      const v1::ListJobsRequest* request,
                                                      v1::ListJobsResponse* response) {
  return FinishGuarded(context, "ListJobs", [&] {
    const uint64_t after = ParsePageToken(request->page_token());
    uint32_t size = request->page_size() == 0 ? limits::kDefaultListJobsPageSize : request->page_size();
    size = std::min(size, limits::kMaxListJobsPageSize);
    Scheduler::JobPage page = api_.ListJobs(request->include_finished(), after, size);
    for (v1::JobStatus& s : page.jobs) *response->add_jobs() = std::move(s);
    if (page.more) response->set_next_page_token(PageToken(page.last_seq));
    return grpc::Status::OK;
  });
}

grpc::ServerUnaryReactor* RenderServiceImpl::CancelJob(grpc::CallbackServerContext* context,
                                                       const v1::CancelJobRequest* request,
                                                       v1::CancelJobResponse* response) {
  return FinishGuarded(context, "CancelJob", [&] {
    RequireJobId(request->job_id());
    *response->mutable_status() = api_.CancelJob(request->job_id());
    return grpc::Status::OK;
  });
}

grpc::ServerUnaryReactor* RenderServiceImpl::PauseJob(grpc::CallbackServerContext* context,
                                                      const v1::PauseJobRequest* request,
                                                      v1::PauseJobResponse* response) {
  return FinishGuarded(context, "PauseJob", [&] {
    RequireJobId(request->job_id());
    *response->mutable_status() = api_.SetJobPaused(request->job_id(), true);
    return grpc::Status::OK;
  });
}

grpc::ServerUnaryReactor* RenderServiceImpl::ResumeJob(grpc::CallbackServerContext* context,
                                                       const v1::ResumeJobRequest* request,
                                                       v1::ResumeJobResponse* response) {
  return FinishGuarded(context, "ResumeJob", [&] {
    RequireJobId(request->job_id());
    *response->mutable_status() = api_.SetJobPaused(request->job_id(), false);
    return grpc::Status::OK;
  });
}

grpc::ServerUnaryReactor* RenderServiceImpl::DeleteJob(grpc::CallbackServerContext* context,
                                                       const v1::DeleteJobRequest* request,
                                                       v1::DeleteJobResponse* response) {
  // Off the RPC thread: it waits for a flush in progress and removes files.
  return CheckThenWork(
      context, api_.executor(), "DeleteJob", [&] { RequireJobId(request->job_id()); },
      [this, request, response] { *response = api_.DeleteJob(request->job_id()); });
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListWorkers(grpc::CallbackServerContext* context,
                                                         const v1::ListWorkersRequest* /*request*/,
                                                         v1::ListWorkersResponse* response) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  for (v1::WorkerInfo& w : api_.Workers()) *response->add_workers() = std::move(w);
  reactor->Finish(grpc::Status::OK);
  return reactor;
}

grpc::ServerUnaryReactor* RenderServiceImpl::ListJobEvents(grpc::CallbackServerContext* context,
                                                           const v1::ListJobEventsRequest* request,
                                                           v1::ListJobEventsResponse* response) {
  return FinishGuarded(context, "ListJobEvents", [&] {
    RequireJobId(request->job_id());
    uint64_t dropped = 0;
    for (v1::TaskEvent& e : api_.JobEvents(request->job_id(), &dropped))
      *response->add_events() = std::move(e);
    response->set_dropped(dropped);
    return grpc::Status::OK;
  });
}

grpc::ServerWriteReactor<v1::JobUpdate>* RenderServiceImpl::WatchJob(grpc::CallbackServerContext* context,
                                                                     const v1::WatchJobRequest* request) {
  return watches_.Open(context, ClientOf(*context), *request, grpc::Status::OK);
}

grpc::ServerWriteReactor<v1::ImageChunk>* RenderServiceImpl::GetImage(
    grpc::CallbackServerContext* /*context*/, const v1::GetImageRequest* request) {
  const grpc::Status precheck = Guarded("GetImage", [&] {
    RequireJobId(request->job_id());
    return grpc::Status::OK;
  });
  const std::string job_id = request->job_id();
  // The EXR is encoded once into an anonymous temporary file (tmpfile: gone when closed, even if
  // the coordinator dies) and streamed from there one chunk at a time, so an unread stream holds
  // one chunk, not the whole image (buffered_stream.h).
  return ChunkedStreamReactor<v1::ImageChunk>::Start(api_.executor(), "GetImage", precheck, [this, job_id] {
    v1::JobStatus status;
    const ResolvedImage image = api_.JobImage(job_id, &status);
    struct State {
      std::unique_ptr<std::FILE, int (*)(std::FILE*)> file{std::tmpfile(), &std::fclose};
      uint64_t size = 0;
      uint32_t count = 0, next = 0;
      uint64_t samples_merged = 0;
    };
    auto state = std::make_shared<State>();
    if (!state->file) throw SystemError("GetImage: cannot create a temporary file for the image");
    {
      const std::string exr = EncodeSnapshot(image);
      if (std::fwrite(exr.data(), 1, exr.size(), state->file.get()) != exr.size() ||
          std::fflush(state->file.get()) != 0)
        throw SystemError("GetImage: cannot write the image to a temporary file");
      state->size = exr.size();
    }
    std::rewind(state->file.get());
    state->count = uint32_t(std::max<uint64_t>(1, (state->size + kImageChunkBytes - 1) / kImageChunkBytes));
    state->samples_merged = image.samples_merged;
    return ChunkedStreamReactor<v1::ImageChunk>::Source([state](v1::ImageChunk* chunk) {
      State& s = *state;
      if (s.next == s.count) return false;
      const uint64_t offset = uint64_t(s.next) * kImageChunkBytes;
      std::string bytes(size_t(std::min<uint64_t>(kImageChunkBytes, s.size - offset)), '\0');
      if (std::fread(bytes.data(), 1, bytes.size(), s.file.get()) != bytes.size())
        throw SystemError("GetImage: cannot read the image back from its temporary file");
      chunk->set_index(s.next++);
      chunk->set_count(s.count);
      chunk->set_exr_bytes(std::move(bytes));
      chunk->set_samples_merged(s.samples_merged);
      return true;
    });
  });
}

}  // namespace pf::server
