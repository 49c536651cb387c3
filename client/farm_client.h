#pragma once
// FarmClient: the client side of photonfarm.v1.RenderService, as plain calls that throw RpcError
// (rpc/grpc_channel.h) on failure. Every call has a deadline; WatchJob survives coordinator
// restarts by re-subscribing. Used by `pf` and by the e2e tests (the "real client").

#include <atomic>
#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "proto/convert.h"
#include "proto/limits.h"
#include "rpc/grpc_channel.h"

namespace pf {

class FarmClient {
 public:
  // `timeout_seconds`: deadline of unary calls and of each GetImage stream.
  // `tls`: plaintext unless tls.ca_pem is set.
  FarmClient(const std::string& address, std::string token, double timeout_seconds = 60, ClientTls tls = {});

  photonfarm::v1::UploadSceneResponse UploadScene(const SceneBundle& bundle);
  std::string SubmitJob(const photonfarm::v1::JobSpec& spec);
  photonfarm::v1::JobStatus GetJob(const std::string& job_id);
  // All jobs, fetched in pages of `page_size` (ListJobsRequest.page_size).
  std::vector<photonfarm::v1::JobStatus> ListJobs(bool include_finished,
                                                  uint32_t page_size = limits::kMaxListJobsPageSize);
  photonfarm::v1::JobStatus CancelJob(const std::string& job_id);
  // PauseJob (paused = true) or ResumeJob.
  photonfarm::v1::JobStatus SetJobPaused(const std::string& job_id, bool paused);
  photonfarm::v1::DeleteJobResponse DeleteJob(const std::string& job_id);
  photonfarm::v1::RequeueJobResponse RequeueJob(const photonfarm::v1::RequeueJobRequest& request);
  std::vector<photonfarm::v1::WorkerInfo> ListWorkers();
  photonfarm::v1::ListJobEventsResponse ListJobEvents(const std::string& job_id);
  // The current merged image, reassembled from its chunks: EXR bytes.
  std::string GetImage(const std::string& job_id, uint64_t* samples_merged = nullptr);

  // Streams the job's updates to `on_update` until its final state has been delivered, then
  // returns that status. If the stream breaks (coordinator restarting), re-subscribes with
  // backoff for up to `reconnect_seconds`. Cancel() from another thread ends it with
  // RpcError(CANCELLED). Snapshot images come as whole EXRs in update.image().exr_bytes(): a
  // snapshot sent in several chunks (consecutive updates) is reassembled first.
  photonfarm::v1::JobStatus Watch(const std::string& job_id, bool include_images, double min_interval_seconds,
                                  const std::function<void(const photonfarm::v1::JobUpdate&)>& on_update,
                                  double reconnect_seconds = 60);
  void Cancel();  // thread-safe; ends a Watch in progress
  bool cancelled() const { return cancelled_.load(); }

  photonfarm::v1::RenderService::Stub& stub() { return *stub_; }
  const std::string& token() const { return token_; }
  std::chrono::milliseconds timeout() const { return timeout_; }

 private:
  using Stub = photonfarm::v1::RenderService::Stub;
  // One unary call with the token and the per-call deadline; throws RpcError unless it is OK.
  template <typename Request, typename Response>
  Response Call(grpc::Status (Stub::*method)(grpc::ClientContext*, const Request&, Response*),
                const Request& req);

  // A failed call's status as an exception; an UNAVAILABLE over TLS explained first
  // (rpc/tls_diagnosis.h: a refused certificate is not "unreachable").
  [[noreturn]] void Fail(const grpc::Status& status) const;

  std::string address_;
  ClientTls tls_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<photonfarm::v1::RenderService::Stub> stub_;
  std::string token_;
  std::chrono::milliseconds timeout_;
  std::mutex mutex_;
  grpc::ClientContext* active_ = nullptr;
  std::atomic<bool> cancelled_{false};
};

bool IsFinalState(photonfarm::v1::JobState s);

}  // namespace pf
