#pragma once
// The worker's only caller of the coordinator (WorkerService, proto/photonfarm/v1/farm.proto):
// every RPC with its deadline and retry policy, the checks of what arrives (a scene bundle's
// content hash; a map part's offset and checksum, the map's size and digest) and the injected
// faults that act on the wire (worker_faults.h: a map part as received, a result or a piece as
// sent). Callers get plain results and statuses; what they mean for the task is the pull loop's
// business (worker.h) and the obtainers' (scene_obtainer.h, map_obtainer.h).
//
// Deadlines (docs/farm.md, "Worker"): LeaseTask the poll wait + the RPC timeout; ExtendLease the
// heartbeat interval, at most the RPC timeout; CompleteTask the RPC timeout; FailTask the RPC
// timeout, at most 5 s; FetchScene, FetchMap and UploadPhotonChunk the fetch timeout.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/plan/task_executor.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "rpc/grpc_channel.h"
#include "worker/worker_options.h"

namespace pf::worker {

// UNAVAILABLE or DEADLINE_EXCEEDED: the coordinator is away (or too slow), not refusing.
bool IsConnectionError(const grpc::Status& s);

// A fetched map that failed its checks (a part's offset or checksum, another map now under the
// key, too few bytes): fetching again may succeed.
class TransferError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CoordinatorClient {
 public:
  explicit CoordinatorClient(WorkerOptions options);
  CoordinatorClient(const CoordinatorClient&) = delete;
  CoordinatorClient& operator=(const CoordinatorClient&) = delete;

  // True once the channel is ready; waits at most `wait`.
  bool WaitForConnected(std::chrono::milliseconds wait);

  // The LeaseTask long poll, naming this worker, its threads, its build and the map seeds it holds.
  // OK without a task: no task now. CANCELLED at once after CancelPolls.
  grpc::Status LeaseTask(const std::vector<uint64_t>& cached_map_seeds,
                         std::optional<photonfarm::v1::Task>* task);
  // Ends the poll in flight and refuses every later one (a stop request). Thread-safe.
  void CancelPolls();

  // ExtendLease: kGone when the coordinator answers that the lease is no longer this worker's
  // (not ok, NOT_FOUND, FAILED_PRECONDITION, PERMISSION_DENIED), kUnanswered on any other error
  // (`status` says which). `interval`: the heartbeat's.
  struct Extension {
    enum class Answer { kExtended, kGone, kUnanswered } answer = Answer::kUnanswered;
    grpc::Status status;
    double lease_seconds = 0;  // kExtended: the lease's duration from now on (0 = unchanged)
  };
  Extension ExtendLease(const std::string& lease_id, double progress, std::chrono::milliseconds interval);

  // CompleteTask with the task's pixel sums and statistics. While the coordinator is unreachable
  // the result is kept and the call retried: `wait(attempts)` between tries (the loop's backoff),
  // until `give_up` or `stop()`. Each try waits for the channel to reconnect, at most the RPC
  // timeout and never past `until()` (a stop request's grace period; null: give_up).
  struct RetryWhileAway {
    std::chrono::steady_clock::time_point give_up;
    std::function<bool()> stop;
    std::function<void(int attempts)> wait;
    std::function<std::chrono::steady_clock::time_point()> until;
  };
  struct Completion {
    grpc::Status status;  // of the last attempt
    bool merged = false;
    size_t bytes = 0;  // of the request
    int attempts = 0;  // failed ones
  };
  Completion CompleteTask(const photonfarm::v1::Task& task, const TaskOutput& output, const std::string& ctx,
                          const RetryWhileAway& retry);

  // FailTask, tried twice while the coordinator is unreachable, then left to expire (logged).
  void FailTask(const std::string& lease_id, const std::string& ctx, const std::string& reason,
                bool retryable);

  // LeaveFarm: this worker stops on its own (listed offline, not lost). One try of at most 2 s;
  // a coordinator that does not answer lists the worker lost later instead.
  void LeaveFarm();

  // FetchScene: the bundle of `hash`, whose files with `entry` (Task.scene_entry) must hash to it.
  // Throws RpcError, or InputError when they do not.
  SceneBundle FetchScene(const std::string& hash, const std::string& entry);

  // FetchMap: the bytes of the map `ref` names, every part checked as it arrives (a refused
  // transfer is cancelled). Throws TransferError or RpcError. The map's own digest is the
  // caller's to check (ReadNamedPhotonMaps).
  std::string FetchMap(const photonfarm::v1::MapRef& ref, const std::string& ctx);

  // UploadPhotonChunk of a traced piece, in parts of ≤ 1 MiB with their checksums.
  struct Upload {
    grpc::Status status;
    bool accepted = false;
    size_t bytes = 0;  // sent
  };
  Upload UploadPhotonChunk(const std::string& lease_id, std::string bytes);

  // Map transfers refused by their checks so far.
  uint64_t map_parts_refused() const { return map_parts_refused_.load(); }

 private:
  // The deadline, the bearer token and this worker's announced id (limits::kWorkerIdMetadata).
  void Prepare(grpc::ClientContext* context, std::chrono::milliseconds timeout) const;

  WorkerOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<photonfarm::v1::WorkerService::Stub> worker_service_;
  std::atomic<uint64_t> map_parts_refused_{0};

  std::mutex poll_mutex_;                        // guards the two below
  grpc::ClientContext* poll_context_ = nullptr;  // the LeaseTask in flight
  bool polls_cancelled_ = false;
};

}  // namespace pf::worker
