#include "client/farm_client.h"

#include <spdlog/spdlog.h>

#include <thread>

#include "common/core/error.h"
#include "rpc/tls_diagnosis.h"

namespace pf {
namespace v1 = photonfarm::v1;

namespace {

bool IsTransient(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAVAILABLE;
}

template <typename Request>
Request WithJobId(const std::string& job_id) {
  Request req;
  req.set_job_id(job_id);
  return req;
}

}  // namespace

bool IsFinalState(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
}

FarmClient::FarmClient(const std::string& address, std::string token, double timeout_seconds, ClientTls tls)
    : address_(address),
      tls_(std::move(tls)),
      channel_(MakeCoordinatorChannel(address, ChannelOptions{.token = "", .tls = tls_})),
      stub_(v1::RenderService::NewStub(channel_)),
      token_(std::move(token)),
      timeout_(Seconds(timeout_seconds)) {}

template <typename Request, typename Response>
Response FarmClient::Call(grpc::Status (Stub::*method)(grpc::ClientContext*, const Request&, Response*),
                          const Request& req) {
  grpc::ClientContext ctx;
  PrepareContext(&ctx, token_, timeout_);
  Response resp;
  const grpc::Status status = (stub_.get()->*method)(&ctx, req, &resp);
  if (!status.ok()) Fail(status);
  return resp;
}

void FarmClient::Fail(const grpc::Status& status) const {
  throw RpcError(ExplainTlsFailure(status, address_, tls_));
}

v1::UploadSceneResponse FarmClient::UploadScene(const SceneBundle& bundle) {
  v1::UploadSceneRequest req;
  BundleToProto(bundle, req.mutable_bundle());
  return Call(&Stub::UploadScene, req);
}

std::string FarmClient::SubmitJob(const v1::JobSpec& spec) {
  v1::SubmitJobRequest req;
  *req.mutable_spec() = spec;
  return Call(&Stub::SubmitJob, req).job_id();
}

v1::JobStatus FarmClient::GetJob(const std::string& job_id) {
  return Call(&Stub::GetJob, WithJobId<v1::GetJobRequest>(job_id));
}

std::vector<v1::JobStatus> FarmClient::ListJobs(bool include_finished, uint32_t page_size) {
  // Page by page (each answer stays far below gRPC's 4 MiB default, whatever the number of jobs).
  std::vector<v1::JobStatus> jobs;
  v1::ListJobsRequest req;
  req.set_include_finished(include_finished);
  req.set_page_size(page_size);
  do {
    const v1::ListJobsResponse resp = Call(&Stub::ListJobs, req);
    jobs.insert(jobs.end(), resp.jobs().begin(), resp.jobs().end());
    if (!resp.next_page_token().empty() && resp.next_page_token() == req.page_token())
      throw SystemError("ListJobs: the coordinator answered the same page token twice");
    req.set_page_token(resp.next_page_token());
  } while (!req.page_token().empty());
  return jobs;
}

v1::JobStatus FarmClient::CancelJob(const std::string& job_id) {
  return Call(&Stub::CancelJob, WithJobId<v1::CancelJobRequest>(job_id)).status();
}

v1::JobStatus FarmClient::SetJobPaused(const std::string& job_id, bool paused) {
  if (paused) return Call(&Stub::PauseJob, WithJobId<v1::PauseJobRequest>(job_id)).status();
  return Call(&Stub::ResumeJob, WithJobId<v1::ResumeJobRequest>(job_id)).status();
}

v1::DeleteJobResponse FarmClient::DeleteJob(const std::string& job_id) {
  return Call(&Stub::DeleteJob, WithJobId<v1::DeleteJobRequest>(job_id));
}

v1::RequeueJobResponse FarmClient::RequeueJob(const v1::RequeueJobRequest& request) {
  return Call(&Stub::RequeueJob, request);
}

std::vector<v1::WorkerInfo> FarmClient::ListWorkers() {
  const v1::ListWorkersResponse resp = Call(&Stub::ListWorkers, v1::ListWorkersRequest());
  return {resp.workers().begin(), resp.workers().end()};
}

v1::ListJobEventsResponse FarmClient::ListJobEvents(const std::string& job_id) {
  return Call(&Stub::ListJobEvents, WithJobId<v1::ListJobEventsRequest>(job_id));
}

std::string FarmClient::GetImage(const std::string& job_id, uint64_t* samples_merged) {
  grpc::ClientContext ctx;
  PrepareContext(&ctx, token_, timeout_);
  std::unique_ptr<grpc::ClientReader<v1::ImageChunk>> reader =
      stub_->GetImage(&ctx, WithJobId<v1::GetImageRequest>(job_id));
  std::string bytes;
  v1::ImageChunk chunk;
  uint32_t expected = 0, count = 0;
  while (reader->Read(&chunk)) {
    if (chunk.index() != expected)
      throw RpcError(
          grpc::Status(grpc::StatusCode::DATA_LOSS, "GetImage: chunk " + std::to_string(chunk.index()) +
                                                        " arrived, expected " + std::to_string(expected)));
    ++expected;
    count = chunk.count();
    bytes += chunk.exr_bytes();
    if (samples_merged) *samples_merged = chunk.samples_merged();
  }
  if (const grpc::Status status = reader->Finish(); !status.ok()) Fail(status);
  if (expected == 0 || expected != count)
    throw RpcError(grpc::Status(
        grpc::StatusCode::DATA_LOSS,
        "GetImage: received " + std::to_string(expected) + " of " + std::to_string(count) + " chunks"));
  return bytes;
}

void FarmClient::Cancel() {
  std::lock_guard lock(mutex_);
  cancelled_ = true;
  if (active_) active_->TryCancel();
}

v1::JobStatus FarmClient::Watch(const std::string& job_id, bool include_images, double min_interval_seconds,
                                const std::function<void(const v1::JobUpdate&)>& on_update,
                                double reconnect_seconds) {
  v1::WatchJobRequest req;
  req.set_job_id(job_id);
  req.set_include_images(include_images);
  req.set_min_interval_seconds(min_interval_seconds);
  auto broken_since = std::chrono::steady_clock::time_point{};
  int retries = 0;
  while (true) {
    grpc::ClientContext ctx;
    // A watch lasts as long as the job; its deadline only bounds a silent, stuck stream.
    PrepareContext(&ctx, token_, std::chrono::hours(24 * 7));
    {
      std::lock_guard lock(mutex_);
      if (cancelled_) throw RpcError(grpc::Status(grpc::StatusCode::CANCELLED, "watch cancelled"));
      active_ = &ctx;
    }
    std::unique_ptr<grpc::ClientReader<v1::JobUpdate>> reader = stub_->WatchJob(&ctx, req);
    v1::JobUpdate update;
    v1::JobStatus last;
    bool final_seen = false;
    bool any = false;
    std::string chunks;  // a snapshot larger than one message arrives in consecutive updates
    while (reader->Read(&update)) {
      any = true;
      if (update.has_image() && update.image().count() > 1) {
        const v1::ImageChunk& c = update.image();
        if (c.index() == 0) chunks.clear();
        chunks += c.exr_bytes();
        if (c.index() + 1 < c.count()) continue;  // the same status comes again with the next chunk
        v1::ImageChunk* img = update.mutable_image();
        img->set_index(0);
        img->set_count(1);
        img->set_exr_bytes(std::move(chunks));
        chunks.clear();
      }
      last = update.status();
      on_update(update);
      if (IsFinalState(last.state())) final_seen = true;
    }
    const grpc::Status status = reader->Finish();
    {
      std::lock_guard lock(mutex_);
      active_ = nullptr;
    }
    if (final_seen) return last;
    {
      std::lock_guard lock(mutex_);
      if (cancelled_) throw RpcError(grpc::Status(grpc::StatusCode::CANCELLED, "watch cancelled"));
    }
    // A CANCELLED this client did not ask for comes from a coordinator shutting down (its server
    // cancels the streams in flight, including one that subscribed in its last moments): as
    // transient as UNAVAILABLE.
    const bool transient = IsTransient(status) || status.error_code() == grpc::StatusCode::CANCELLED;
    if (status.ok()) {
      // The stream ended without a final state (e.g. the coordinator is shutting down): poll once,
      // and if the coordinator is gone already, re-subscribe as below.
      try {
        last = GetJob(job_id);
        if (IsFinalState(last.state())) {
          v1::JobUpdate u;
          *u.mutable_status() = last;
          on_update(u);
          return last;
        }
      } catch (const RpcError& e) {
        if (!IsTransient(e.status()) && e.code() != grpc::StatusCode::CANCELLED) throw;
      }
    } else if (!transient) {
      throw RpcError(status);
    } else if (retries == 0 && !any) {
      // A refused certificate will not be accepted on the next attempt.
      const grpc::Status explained = ExplainTlsFailure(status, address_, tls_);
      if (explained.error_message() != status.error_message()) throw RpcError(explained);
    }
    // Transient: the coordinator may be restarting. Re-subscribe with a capped backoff.
    const auto now = std::chrono::steady_clock::now();
    if (any || retries == 0) broken_since = now, retries = 0;
    if (now - broken_since > Seconds(reconnect_seconds))
      throw RpcError(status.ok() ? grpc::Status(grpc::StatusCode::UNAVAILABLE, "watch stream ended")
                                 : status);
    if (retries == 0) spdlog::warn("watch {}: {}; re-subscribing", job_id, StatusToString(status));
    ++retries;
    std::this_thread::sleep_for(std::chrono::milliseconds(std::min(2000, 100 << std::min(retries, 5))));
  }
}

}  // namespace pf
