#include "server/rpc/worker_service.h"

#include "proto/limits.h"

#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <mutex>

#include "common/core/error.h"
#include "common/core/sha256.h"
#include "common/plan/frame_tasks.h"
#include "proto/convert.h"
#include "server/errors.h"
#include "server/rpc/buffered_stream.h"
#include "server/rpc/status_mapping.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

namespace {

void FillTask(const Lease& lease, v1::Task* task, CoordinatorApi& api) {
  // What every task carries: its lease, its scene and the job's settings.
  task->set_job_id(lease.job_id);
  task->set_attempt(lease.attempt);
  task->set_lease_id(lease.lease_id);
  task->set_lease_seconds(lease.lease_seconds);
  task->set_scene_hash(lease.config->scene_hash);
  task->set_scene_entry(lease.config->scene_entry);
  SettingsToProto(lease.config->settings, task->mutable_settings());
  if (lease.config->plan.kind == PlanKind::kProgressive)
    WriteProgressiveAlpha(lease.config->settings, task->mutable_settings());
  if (lease.chunk) {
    // A piece of a map to trace: no pixels, no camera (Task.trace_chunk).
    task->set_task_id(lease.task_id);
    task->set_map_index(lease.task.map_index);
    task->set_map_seed(lease.task.map_seed);
    v1::TraceChunk* c = task->mutable_trace_chunk();
    c->set_map_key(lease.chunk->map_key);
    c->set_photon_begin(lease.chunk->photon_begin);
    c->set_photon_end(lease.chunk->photon_end);
    c->set_chunk_index(lease.chunk->chunk_index);
    c->set_chunk_count(lease.chunk->chunk_count);
    return;
  }
  if (const std::optional<BuiltMap> map = api.MapFor(lease.job_id, lease.task.map_index)) {
    v1::MapRef* ref = task->mutable_map();
    ref->set_map_key(map->key);
    ref->set_bytes(map->bytes);
    ref->set_digest(map->digest);
  }
  // An animation's task is its frame's (common/plan/frame_tasks.h): that camera, the frame's own rows.
  TaskSpecToProto(FrameLocalTask(lease.task, lease.config->camera.height), task);
  CameraToProto(lease.config->CameraOf(lease.task), task->mutable_camera());
}

void RequireLeaseId(const std::string& id) {
  limits::CheckId(id, "lease_id");
}

// Every call about a lease names its caller: a lease is bound to the worker it was leased to
// (docs/security.md, "Leases are bound to their worker").
void RequireWorkerId(const std::string& id) {
  limits::CheckId(id, "worker_id", limits::kMaxWorkerIdBytes);
}

// A unary call the gate refused: answered at once.
grpc::ServerUnaryReactor* Refused(grpc::CallbackServerContext* context, const grpc::Status& status) {
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(status);
  return reactor;
}

// A streamed fetch's precheck: the gate, then the id the request names (`field`), read only once
// the call is admitted.
grpc::Status AdmitWithId(const WorkerGate& gate, const grpc::CallbackServerContext& context, const char* rpc,
                         const std::string& id, const char* field) {
  grpc::Status status = gate.Admit(context);
  if (!status.ok()) return status;
  return Guarded(rpc, [&] {
    limits::CheckId(id, field);
    return grpc::Status::OK;
  });
}

grpc::Status NotHolder() {
  return grpc::Status(grpc::StatusCode::PERMISSION_DENIED,
                      "lease_id: the lease is held by another worker; nothing was changed");
}

// One parked long poll. The state shared with the scheduler's callback lives in `State`, so the
// reactor is only touched until it is finished (it deletes itself in OnDone).
class LeaseReactor final : public grpc::ServerUnaryReactor {
 public:
  LeaseReactor(CoordinatorApi& api, grpc::CallbackServerContext* context, const v1::LeaseTaskRequest* request,
               v1::LeaseTaskResponse* response)
      : api_(api), state_(std::make_shared<State>()) {
    LeaseRequest lr;
    double wait = 0;
    const grpc::Status status = Guarded("LeaseTask", [&] {
      limits::CheckId(request->worker_id(), "worker_id", limits::kMaxWorkerIdBytes);
      wait = request->wait_seconds();
      if (!std::isfinite(wait) || wait < 0) throw InputError("wait_seconds: must be a finite number >= 0");
      wait = std::min(wait, kMaxLeaseWaitSeconds);
      const std::optional<std::string> refused = api.WorkerSeen({.worker_id = request->worker_id(),
                                                                 .peer = context->peer(),
                                                                 .version = request->worker_version(),
                                                                 .threads = request->threads()});
      if (refused) return grpc::Status(grpc::StatusCode::FAILED_PRECONDITION, *refused);
      lr.worker_id = request->worker_id();
      lr.cached_map_seeds.assign(request->cached_map_seeds().begin(), request->cached_map_seeds().end());
      return grpc::Status::OK;
    });
    if (!status.ok()) {
      Finish(status);
      return;
    }
    std::shared_ptr<State> state = state_;
    // May run before LeaseOrWait returns; after Finish `this` may be gone, so only `state` and
    // locals are used below.
    CoordinatorApi* coordinator = &api;
    auto deliver = [this, context, response, coordinator](std::optional<Lease> lease) {
      if (lease && context->IsCancelled()) {
        // Undelivered: queued again at once (a piece too: the lease's kind decides), not left to run out.
        coordinator->ReturnLease(lease->lease_id);
        lease.reset();
      }
      if (lease) {
        FillTask(*lease, response->mutable_task(), *coordinator);
        spdlog::debug("job {} task {}: lease {} sent", lease->job_id, lease->task_id, lease->lease_id);
      }
      Finish(grpc::Status::OK);
    };
    const uint64_t waiter = coordinator->LeaseOrWait(lr, wait, std::move(deliver));
    bool cancel_now = false;
    {
      std::lock_guard lock(state->mu);
      state->waiter = waiter;
      cancel_now = state->cancelled && waiter != 0;
    }
    if (cancel_now) coordinator->CancelWait(waiter);
  }

  void OnCancel() override {
    uint64_t waiter = 0;
    {
      std::lock_guard lock(state_->mu);
      state_->cancelled = true;
      waiter = state_->waiter;
    }
    if (waiter != 0) api_.CancelWait(waiter);  // answers "no task" if still parked
  }
  void OnDone() override { delete this; }

 private:
  struct State {
    std::mutex mu;
    uint64_t waiter = 0;
    bool cancelled = false;
  };
  CoordinatorApi& api_;
  std::shared_ptr<State> state_;
};

}  // namespace

grpc::ServerUnaryReactor* WorkerServiceImpl::LeaseTask(grpc::CallbackServerContext* context,
                                                       const v1::LeaseTaskRequest* request,
                                                       v1::LeaseTaskResponse* response) {
  if (grpc::Status admitted = gate_.Admit(*context); !admitted.ok()) return Refused(context, admitted);
  return new LeaseReactor(api_, context, request, response);
}

grpc::ServerUnaryReactor* WorkerServiceImpl::ExtendLease(grpc::CallbackServerContext* context,
                                                         const v1::ExtendLeaseRequest* request,
                                                         v1::ExtendLeaseResponse* response) {
  if (grpc::Status admitted = gate_.Admit(*context); !admitted.ok()) return Refused(context, admitted);
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  grpc::Status status = Guarded("ExtendLease", [&] {
    RequireLeaseId(request->lease_id());
    RequireWorkerId(request->worker_id());
    const ExtendResult r = api_.ExtendLease(request->lease_id(), request->worker_id(), request->progress());
    if (r.not_holder) return NotHolder();
    response->set_ok(r.ok);
    response->set_lease_seconds(r.lease_seconds);
    return grpc::Status::OK;
  });
  reactor->Finish(status);
  return reactor;
}

grpc::ServerUnaryReactor* WorkerServiceImpl::CompleteTask(grpc::CallbackServerContext* context,
                                                          const v1::CompleteTaskRequest* request,
                                                          v1::CompleteTaskResponse* response) {
  if (grpc::Status admitted = gate_.Admit(*context); !admitted.ok()) return Refused(context, admitted);
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  CompleteResult result;
  grpc::Status status = Guarded("CompleteTask", [&] {
    RequireLeaseId(request->lease_id());
    RequireWorkerId(request->worker_id());
    RadiancePart part = RadiancePart::kAll;
    switch (request->part()) {
      case v1::RADIANCE_PART_ALL:
        break;
      case v1::RADIANCE_PART_MAPPED:
        part = RadiancePart::kMapped;
        break;
      case v1::RADIANCE_PART_UNMAPPED:
        part = RadiancePart::kUnmapped;
        break;
      default:
        return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                            "part: unknown value " + std::to_string(int(request->part())));
    }
    const auto& sums = request->rgb_sums();
    const v1::TaskStats& st = request->stats();
    result = api_.CompleteTask(
        request->lease_id(), request->worker_id(), std::span<const float>(sums.data(), size_t(sums.size())),
        part, {.photons_emitted = st.photons_emitted(), .seconds = st.map_seconds() + st.render_seconds()});
    if (result.status == CompleteStatus::kNotHolder) return NotHolder();
    if (result.status == CompleteStatus::kRejected)
      return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                          "rgb_sums: result rejected, the task is re-queued: " + result.reason);
    return grpc::Status::OK;
  });
  if (!status.ok() || result.status != CompleteStatus::kMerged) {
    response->set_merged(false);
    reactor->Finish(status);
    return reactor;
  }
  const v1::TaskStats& st = request->stats();
  spdlog::debug("job {} task {}: result merged (map {:.3f} s{}, render {:.3f} s, {} photons stored)",
                result.job_id, result.task_id, st.map_seconds(), st.map_cache_hit() ? " cached" : "",
                st.render_seconds(), st.photons_stored());
  response->set_merged(true);
  // merged = true only once the result is stored (docs/farm.md "Durability", D1); not stored:
  // UNAVAILABLE, so the worker never counts it as merged.
  const auto& sums = request->rgb_sums();
  api_.AcknowledgeWhenStored(
      result, std::span<const float>(sums.data(), size_t(sums.size())),
      [reactor](const std::string& not_stored) {
        if (not_stored.empty()) {
          reactor->Finish(grpc::Status::OK);
          return;
        }
        reactor->Finish(grpc::Status(grpc::StatusCode::UNAVAILABLE,
                                     "the coordinator merged the result but could not store it (" +
                                         not_stored + "); it is not acknowledged"));
      });
  return reactor;
}

grpc::ServerUnaryReactor* WorkerServiceImpl::FailTask(grpc::CallbackServerContext* context,
                                                      const v1::FailTaskRequest* request,
                                                      v1::FailTaskResponse* /*response*/) {
  if (grpc::Status admitted = gate_.Admit(*context); !admitted.ok()) return Refused(context, admitted);
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  grpc::Status status = Guarded("FailTask", [&] {
    RequireLeaseId(request->lease_id());
    RequireWorkerId(request->worker_id());
    std::string reason = limits::Printable(request->reason(), limits::kMaxReasonBytes);
    if (reason.empty()) reason = "no reason given";
    const FailOutcome outcome =
        api_.FailTask(request->lease_id(), request->worker_id(), reason, request->retryable());
    switch (outcome) {
      case FailOutcome::kFailed:
        return grpc::Status::OK;
      case FailOutcome::kUnknownLease:
        return grpc::Status(grpc::StatusCode::NOT_FOUND,
                            "lease_id: unknown, expired or finished lease; nothing was changed");
      case FailOutcome::kNotHolder:
        return NotHolder();
    }
    return grpc::Status::OK;
  });
  reactor->Finish(status);
  return reactor;
}

grpc::ServerUnaryReactor* WorkerServiceImpl::LeaveFarm(grpc::CallbackServerContext* context,
                                                       const v1::LeaveFarmRequest* request,
                                                       v1::LeaveFarmResponse* /*response*/) {
  if (grpc::Status admitted = gate_.Admit(*context); !admitted.ok()) return Refused(context, admitted);
  grpc::ServerUnaryReactor* reactor = context->DefaultReactor();
  reactor->Finish(Guarded("LeaveFarm", [&] {
    RequireWorkerId(request->worker_id());
    api_.WorkerLeft(request->worker_id());
    return grpc::Status::OK;
  }));
  return reactor;
}

grpc::ServerWriteReactor<v1::SceneFile>* WorkerServiceImpl::FetchScene(grpc::CallbackServerContext* context,
                                                                       const v1::FetchSceneRequest* request) {
  const grpc::Status precheck =
      AdmitWithId(gate_, *context, "FetchScene", request->scene_hash(), "scene_hash");
  const std::string hash = precheck.ok() ? request->scene_hash() : std::string();
  // Streamed from the stored files, one chunk of ≤ kSceneChunkBytes at a time (buffered_stream.h);
  // a file larger than a chunk continues in the next message with the same path, an empty file
  // is one empty message.
  return ChunkedStreamReactor<v1::SceneFile>::Start(api_.executor(), "FetchScene", precheck, [this, hash] {
    struct State {
      std::vector<std::pair<std::string, std::filesystem::path>> files;
      size_t next = 0;  // index of the file being read
      std::ifstream in;
      bool sent = false;  // a message of files[next] was sent
    };
    auto state = std::make_shared<State>();
    state->files = api_.SceneFiles(hash);
    return ChunkedStreamReactor<v1::SceneFile>::Source([state](v1::SceneFile* message) {
      State& s = *state;
      while (s.next < s.files.size()) {
        const auto& [path, file] = s.files[s.next];
        if (!s.in.is_open()) {
          s.in.open(file, std::ios::binary);
          if (!s.in) throw SystemError(file.string() + ": cannot read stored scene file");
        }
        std::string content(kSceneChunkBytes, '\0');
        s.in.read(content.data(), std::streamsize(content.size()));
        if (s.in.bad()) throw SystemError(file.string() + ": cannot read stored scene file");
        content.resize(size_t(s.in.gcount()));
        if (!content.empty() || !s.sent) {
          message->set_path(path);
          message->set_content(std::move(content));
          s.sent = true;
          return true;
        }
        s.in.close();
        s.in.clear();
        s.sent = false;
        ++s.next;
      }
      return false;
    });
  });
}

namespace {

// UploadPhotonChunk: collects the parts (cheap bookkeeping on gRPC's thread), then checks every
// checksum, the whole digest and the piece itself on an executor thread (S4: callbacks do not block).
class ChunkUploadReactor final : public grpc::ServerReadReactor<v1::PhotonChunkPart> {
 public:
  // `admitted`: the gate's answer; a refused stream is finished before anything is read.
  ChunkUploadReactor(CoordinatorApi& api, v1::UploadPhotonChunkResponse* response,
                     const grpc::Status& admitted)
      : api_(api), response_(response) {
    if (!admitted.ok()) {
      Finish(admitted);
      return;
    }
    StartRead(&part_);
  }
  void OnReadDone(bool ok) override {
    if (!ok) {
      if (!api_.executor().Post([this] { End(Verify()); }))
        End(grpc::Status(grpc::StatusCode::UNAVAILABLE, "coordinator busy or shutting down"));
      return;
    }
    if (parts_ == 0) {
      lease_id_ = part_.lease_id();
      worker_id_ = part_.worker_id();
      total_ = part_.total_bytes();
      digest_ = part_.digest();
      if (total_ > kMaxPhotonChunkBytes) {
        Finish(grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "total_bytes: " + std::to_string(total_) +
                                                                      " exceeds the limit " +
                                                                      std::to_string(kMaxPhotonChunkBytes)));
        return;
      }
      // Admitted before anything is buffered: a live piece lease, one stream at a time (a stale
      // lease answers at once, accepted = false, as a late piece would after its upload).
      const grpc::Status well_formed = Guarded("UploadPhotonChunk", [&] {
        RequireLeaseId(lease_id_);
        RequireWorkerId(worker_id_);
        return grpc::Status::OK;
      });
      if (!well_formed.ok()) {
        Finish(well_formed);
        return;
      }
      // Guarded: this runs in a reactor callback, where an exception would end the process.
      DistributedMaps::UploadAdmission admission = DistributedMaps::UploadAdmission::kNotLive;
      const grpc::Status begun = Guarded("UploadPhotonChunk", [&] {
        admission = api_.BeginPieceUpload(lease_id_, worker_id_);
        return grpc::Status::OK;
      });
      if (!begun.ok()) {
        Finish(begun);
        return;
      }
      switch (admission) {
        case DistributedMaps::UploadAdmission::kNotLive:
          response_->set_accepted(false);
          Finish(grpc::Status::OK);
          return;
        case DistributedMaps::UploadAdmission::kNotHolder:
          Finish(NotHolder());
          return;
        case DistributedMaps::UploadAdmission::kBusy:
          Finish(grpc::Status(grpc::StatusCode::ALREADY_EXISTS,
                              "lease_id: an upload for this piece lease is already in progress"));
          return;
        case DistributedMaps::UploadAdmission::kAdmitted:
          admitted_ = true;
          break;
      }
      // The declared size is reserved up to 16 MiB only; past that the buffer grows with the
      // bytes that really arrive.
      bytes_.reserve(size_t(std::min<uint64_t>(total_, uint64_t(16) << 20)));
    }
    if (part_.data().size() > kMapPartBytes || part_.offset() != bytes_.size() ||
        bytes_.size() + part_.data().size() > total_) {
      End(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                       "parts[" + std::to_string(parts_) + "]: offset " + std::to_string(part_.offset()) +
                           " / size " + std::to_string(part_.data().size()) + " do not continue the " +
                           std::to_string(bytes_.size()) + " bytes received (of " + std::to_string(total_) +
                           ", parts ≤ 1 MiB)"));
      return;
    }
    part_sums_.push_back(part_.sha256());
    part_ends_.push_back(bytes_.size() + part_.data().size());
    bytes_ += part_.data();
    ++parts_;
    StartRead(&part_);
  }
  void OnDone() override {
    if (admitted_) api_.EndPieceUpload(lease_id_);  // not reached when End ran (admitted_ is false then)
    delete this;
  }

 private:
  // Finishes an admitted stream: its admission is released first, so a client that opens the next
  // stream as soon as it has this status is admitted.
  void End(const grpc::Status& status) {
    if (admitted_) {
      api_.EndPieceUpload(lease_id_);
      admitted_ = false;
    }
    Finish(status);
  }

  grpc::Status Verify() {
    return Guarded("UploadPhotonChunk", [&] {
      RequireLeaseId(lease_id_);
      size_t begin = 0;
      for (size_t i = 0; i < part_sums_.size(); ++i) {
        if (Sha256Hex(std::string_view(bytes_).substr(begin, part_ends_[i] - begin)) != part_sums_[i])
          throw InputError("parts[" + std::to_string(i) +
                           "].sha256: checksum mismatch: the piece is refused");
        begin = part_ends_[i];
      }
      if (bytes_.size() != total_)
        throw InputError("total_bytes: " + std::to_string(bytes_.size()) + " bytes received of " +
                         std::to_string(total_));
      if (Sha256Hex(bytes_) != digest_) throw InputError("digest: mismatch: the piece is refused");
      const DistributedMaps::Accepted a = api_.AcceptPiece(lease_id_, worker_id_, bytes_);
      if (a == DistributedMaps::Accepted::kNotHolder) return NotHolder();
      response_->set_accepted(a == DistributedMaps::Accepted::kStored);
      return grpc::Status::OK;
    });
  }

  CoordinatorApi& api_;
  v1::UploadPhotonChunkResponse* response_;
  v1::PhotonChunkPart part_;
  std::string lease_id_, worker_id_, digest_, bytes_;
  uint64_t total_ = 0;
  size_t parts_ = 0;
  bool admitted_ = false;
  std::vector<std::string> part_sums_;
  std::vector<size_t> part_ends_;
};

}  // namespace

grpc::ServerReadReactor<v1::PhotonChunkPart>* WorkerServiceImpl::UploadPhotonChunk(
    grpc::CallbackServerContext* context, v1::UploadPhotonChunkResponse* response) {
  return new ChunkUploadReactor(api_, response, gate_.Admit(*context));
}

grpc::ServerWriteReactor<v1::MapBytes>* WorkerServiceImpl::FetchMap(grpc::CallbackServerContext* context,
                                                                    const v1::FetchMapRequest* request) {
  const grpc::Status precheck = AdmitWithId(gate_, *context, "FetchMap", request->map_key(), "map_key");
  const std::string key = precheck.ok() ? request->map_key() : std::string();
  // Streamed from the file one part at a time (like FetchScene), each part with its checksum.
  return ChunkedStreamReactor<v1::MapBytes>::Start(api_.executor(), "FetchMap", precheck, [this, key] {
    const BuiltMapFile map = api_.MapFile(key);
    struct State {
      std::ifstream in;
      uint64_t offset = 0, total = 0;
      std::string digest;
      bool sent = false;
    };
    auto state = std::make_shared<State>();
    state->in.open(map.file, std::ios::binary);
    if (!state->in) throw SystemError(map.file.string() + ": cannot read the built map");
    state->total = std::filesystem::file_size(map.file);
    state->digest = map.digest;
    return ChunkedStreamReactor<v1::MapBytes>::Source([state](v1::MapBytes* message) {
      State& s = *state;
      if (s.offset >= s.total && s.sent) return false;
      std::string data(size_t(std::min<uint64_t>(kMapPartBytes, s.total - s.offset)), '\0');
      s.in.read(data.data(), std::streamsize(data.size()));
      if (!s.in) throw SystemError("cannot read the built map");
      message->set_offset(s.offset);
      message->set_sha256(Sha256Hex(data));
      message->set_total_bytes(s.total);
      message->set_digest(s.digest);
      s.offset += data.size();
      message->set_data(std::move(data));
      s.sent = true;
      return true;
    });
  });
}

}  // namespace pf::server
