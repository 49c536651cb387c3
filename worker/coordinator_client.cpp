#include "worker/coordinator_client.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <string_view>

#include "common/core/error.h"
#include "common/core/sha256.h"
#include "photonfarm_version.h"
#include "proto/limits.h"

namespace pf::worker {
namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

namespace {

constexpr size_t kPartBytes = size_t(1) << 20;  // parts of uploads (≤ 1 MiB, as the coordinator's)

std::string Short(const std::string& key) {
  return key.substr(0, 12);
}

}  // namespace

void CoordinatorClient::Prepare(grpc::ClientContext* context, std::chrono::milliseconds timeout) const {
  PrepareContext(context, options_.token, timeout);
  // Named in every call, so that a refused one is listed under this worker (pf workers).
  context->AddMetadata(limits::kWorkerIdMetadata, limits::AnnouncedWorkerId(options_.worker_id));
}

bool IsConnectionError(const grpc::Status& s) {
  return s.error_code() == grpc::StatusCode::UNAVAILABLE ||
         s.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
}

CoordinatorClient::CoordinatorClient(WorkerOptions options)
    : options_(std::move(options)),
      channel_(MakeCoordinatorChannel(options_.coordinator,
                                      ChannelOptions{.token = options_.token, .tls = options_.tls})),
      worker_service_(v1::WorkerService::NewStub(channel_)) {}

bool CoordinatorClient::WaitForConnected(std::chrono::milliseconds wait) {
  return channel_->WaitForConnected(std::chrono::system_clock::now() + wait);
}

grpc::Status CoordinatorClient::LeaseTask(const std::vector<uint64_t>& cached_map_seeds,
                                          std::optional<v1::Task>* task) {
  v1::LeaseTaskRequest req;
  req.set_worker_id(options_.worker_id);
  req.set_threads(uint32_t(options_.threads));
  for (uint64_t s : cached_map_seeds) req.add_cached_map_seeds(s);
  req.set_wait_seconds(options_.poll_seconds);
  req.set_worker_version(PF_VERSION);
  grpc::ClientContext ctx;
  Prepare(&ctx, Seconds(options_.poll_seconds + options_.rpc_timeout_seconds));
  {
    std::lock_guard lock(poll_mutex_);
    if (polls_cancelled_) return grpc::Status::CANCELLED;
    poll_context_ = &ctx;
  }
  v1::LeaseTaskResponse resp;
  const grpc::Status status = worker_service_->LeaseTask(&ctx, req, &resp);
  {
    std::lock_guard lock(poll_mutex_);
    poll_context_ = nullptr;
  }
  if (status.ok() && resp.has_task()) *task = resp.task();
  return status;
}

void CoordinatorClient::CancelPolls() {
  std::lock_guard lock(poll_mutex_);
  polls_cancelled_ = true;
  if (poll_context_) poll_context_->TryCancel();
}

CoordinatorClient::Extension CoordinatorClient::ExtendLease(const std::string& lease_id, double progress,
                                                            std::chrono::milliseconds interval) {
  v1::ExtendLeaseRequest req;
  req.set_lease_id(lease_id);
  req.set_worker_id(options_.worker_id);  // leases are bound to their worker
  req.set_progress(progress);
  v1::ExtendLeaseResponse resp;
  grpc::ClientContext cctx;
  // Fails at once while the channel is down (no wait_for_ready): the lease keeper's thread must
  // stop promptly on a stop or an abort. CompleteTask's waiting call and gRPC's backup poller
  // drive the reconnection.
  Prepare(&cctx, std::min(interval, Seconds(options_.rpc_timeout_seconds)));
  Extension e;
  e.status = worker_service_->ExtendLease(&cctx, req, &resp);
  if (e.status.ok()) {
    e.answer = resp.ok() ? Extension::Answer::kExtended : Extension::Answer::kGone;
    e.lease_seconds = resp.lease_seconds();
  } else if (e.status.error_code() == grpc::StatusCode::NOT_FOUND ||
             e.status.error_code() == grpc::StatusCode::FAILED_PRECONDITION ||
             e.status.error_code() == grpc::StatusCode::PERMISSION_DENIED) {  // not this worker's lease
    e.answer = Extension::Answer::kGone;
  }
  return e;
}

CoordinatorClient::Completion CoordinatorClient::CompleteTask(const v1::Task& task, const TaskOutput& output,
                                                              const std::string& ctx,
                                                              const RetryWhileAway& retry) {
  v1::CompleteTaskRequest req;
  req.set_lease_id(task.lease_id());
  req.set_worker_id(options_.worker_id);
  req.set_part(task.part());  // what was rendered (TaskSpecFromProto accepted this part)
  if (options_.faults) {      // tests only: a malicious worker
    std::vector<float> sums = output.rgb_sums;
    options_.faults->OnResult(sums);
    req.mutable_rgb_sums()->Assign(sums.begin(), sums.end());
  } else {
    req.mutable_rgb_sums()->Assign(output.rgb_sums.begin(), output.rgb_sums.end());
  }
  v1::TaskStats* st = req.mutable_stats();
  st->set_photons_emitted(output.photons_emitted);
  st->set_photons_stored(output.photons_stored);
  st->set_rays(output.rays);
  st->set_map_seconds(output.map_seconds);
  st->set_render_seconds(output.render_seconds);
  st->set_map_cache_hit(output.map_cache_hit);
  Completion c;
  c.bytes = req.ByteSizeLong();
  while (true) {
    grpc::ClientContext cctx;
    const auto until = retry.until ? std::min(retry.until(), retry.give_up) : retry.give_up;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    Prepare(&cctx, std::clamp(left, std::chrono::milliseconds(100),
                              std::chrono::duration_cast<std::chrono::milliseconds>(
                                  Seconds(options_.rpc_timeout_seconds))));
    // While the coordinator is unreachable the call waits for the channel to reconnect instead of
    // failing at once: with the synchronous API a waiting call is what drives the reconnection (a
    // worker cut off by a partition never reconnected without it: tests/deploy/multihost_test.py).
    cctx.set_wait_for_ready(true);
    v1::CompleteTaskResponse resp;
    c.status = worker_service_->CompleteTask(&cctx, req, &resp);
    c.merged = c.status.ok() && resp.merged();
    if (!IsConnectionError(c.status)) return c;  // done, or refused: retrying would not change it
    ++c.attempts;
    if (Clock::now() >= retry.give_up || retry.stop()) return c;
    if (c.attempts == 1)
      spdlog::warn("CompleteTask {}: {}; keeping the result and retrying", ctx, StatusToString(c.status));
    retry.wait(c.attempts);
  }
}

void CoordinatorClient::FailTask(const std::string& lease_id, const std::string& ctx,
                                 const std::string& reason, bool retryable) {
  v1::FailTaskRequest req;
  req.set_lease_id(lease_id);
  req.set_worker_id(options_.worker_id);  // only the lease's holder may fail it
  req.set_reason(reason);
  req.set_retryable(retryable);
  for (int attempt = 0; attempt < 2; ++attempt) {
    grpc::ClientContext cctx;
    Prepare(&cctx, Seconds(std::min(options_.rpc_timeout_seconds, 5.0)));
    v1::FailTaskResponse resp;
    const grpc::Status status = worker_service_->FailTask(&cctx, req, &resp);
    if (status.ok() || !IsConnectionError(status)) {
      if (!status.ok()) spdlog::warn("FailTask {}: {}", ctx, StatusToString(status));
      return;
    }
  }
  spdlog::warn("FailTask {}: coordinator unreachable; the lease will expire", ctx);
}

void CoordinatorClient::LeaveFarm() {
  v1::LeaveFarmRequest req;
  req.set_worker_id(options_.worker_id);
  grpc::ClientContext cctx;
  Prepare(&cctx, std::chrono::milliseconds(2000));
  v1::LeaveFarmResponse resp;
  const grpc::Status status = worker_service_->LeaveFarm(&cctx, req, &resp);
  if (!status.ok())
    spdlog::info("LeaveFarm: {} (the coordinator will list this worker lost)", StatusToString(status));
}

SceneBundle CoordinatorClient::FetchScene(const std::string& hash, const std::string& entry) {
  if (entry.empty()) throw InputError("task for scene " + hash + " without scene_entry");
  grpc::ClientContext ctx;
  Prepare(&ctx, Seconds(options_.fetch_timeout_seconds));
  v1::FetchSceneRequest req;
  req.set_scene_hash(hash);
  std::unique_ptr<grpc::ClientReader<v1::SceneFile>> reader = worker_service_->FetchScene(&ctx, req);
  SceneBundle bundle;
  v1::SceneFile chunk;
  while (reader->Read(&chunk)) {
    if (!bundle.files.empty() && bundle.files.back().first == chunk.path())
      bundle.files.back().second += chunk.content();  // a large file continues in the next message
    else
      bundle.files.emplace_back(chunk.path(), chunk.content());
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) throw RpcError(status);
  // The stream carries files only; the entry comes with the task (Task.scene_entry, always set
  // by the coordinator from its scene store) and is part of the content hash.
  bundle.entry = entry;
  if (BundleHash(bundle) != hash)
    throw InputError("FetchScene " + hash + ": the " + std::to_string(bundle.files.size()) +
                     " files received with entry " + entry + " do not match the hash");
  return bundle;
}

std::string CoordinatorClient::FetchMap(const v1::MapRef& ref, const std::string& ctx) {
  grpc::ClientContext cctx;
  Prepare(&cctx, Seconds(options_.fetch_timeout_seconds));
  v1::FetchMapRequest req;
  req.set_map_key(ref.map_key());
  std::unique_ptr<grpc::ClientReader<v1::MapBytes>> reader(worker_service_->FetchMap(&cctx, req));
  std::string bytes;
  bytes.reserve(size_t(std::min<uint64_t>(ref.bytes(), uint64_t(1) << 34)));
  v1::MapBytes part;
  uint32_t index = 0;
  std::string refused;
  while (reader->Read(&part)) {
    std::string data = part.data();
    if (options_.faults) options_.faults->OnMapPart(data, index, ref.map_key());  // tests only
    if (refused.empty()) {
      if (part.offset() != bytes.size())
        refused = "part " + std::to_string(index) + " at offset " + std::to_string(part.offset()) +
                  ", expected " + std::to_string(bytes.size());
      else if (Sha256Hex(data) != part.sha256())
        refused = "part " + std::to_string(index) + ": checksum mismatch";
      else if (part.total_bytes() != ref.bytes() || part.digest() != ref.digest())
        refused = "the coordinator now holds another map under this key";
      if (!refused.empty()) cctx.TryCancel();  // nothing more of this transfer is used
    }
    if (refused.empty()) bytes += data;
    ++index;
  }
  const grpc::Status status = reader->Finish();
  if (!refused.empty()) {
    ++map_parts_refused_;
    throw TransferError("map " + Short(ref.map_key()) + " for " + ctx + ": " + refused + ": refused");
  }
  if (!status.ok()) throw RpcError(status);
  if (bytes.size() != ref.bytes())
    throw TransferError("map " + Short(ref.map_key()) + ": " + std::to_string(bytes.size()) + " of " +
                        std::to_string(ref.bytes()) + " bytes arrived");
  return bytes;
}

CoordinatorClient::Upload CoordinatorClient::UploadPhotonChunk(const std::string& lease_id,
                                                               std::string bytes) {
  if (options_.faults) options_.faults->OnPiece(bytes);  // tests only: a malicious worker
  grpc::ClientContext cctx;
  Prepare(&cctx, Seconds(options_.fetch_timeout_seconds));
  v1::UploadPhotonChunkResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::PhotonChunkPart>> writer(
      worker_service_->UploadPhotonChunk(&cctx, &response));
  size_t offset = 0;
  bool first = true;
  while (first || offset < bytes.size()) {
    v1::PhotonChunkPart part;
    if (first) {
      part.set_lease_id(lease_id);
      part.set_worker_id(options_.worker_id);
      part.set_total_bytes(bytes.size());
      part.set_digest(Sha256Hex(bytes));
    }
    const std::string_view data = std::string_view(bytes).substr(offset, kPartBytes);
    part.set_offset(offset);
    part.set_data(std::string(data));
    part.set_sha256(Sha256Hex(data));
    offset += data.size();
    first = false;
    if (!writer->Write(part)) break;  // the server ended the call: Finish says why
  }
  writer->WritesDone();
  Upload u;
  u.status = writer->Finish();
  u.accepted = u.status.ok() && response.accepted();
  u.bytes = bytes.size();
  return u;
}

}  // namespace pf::worker
