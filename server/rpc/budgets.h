#pragma once
// The coordinator's budgets (docs/security.md, "Budgets"): how much one client, and all clients
// together, may make the coordinator hold — queued and running jobs, their tasks and pixels,
// WatchJob streams, uploads in flight and stored scene bytes. A valid client token is not a
// licence to exhaust the coordinator: every budget is checked *before* the work it bounds (the
// task list's expansion, the scene's load, the watcher's first snapshot) and refused with
// RESOURCE_EXHAUSTED (LimitError) naming the request field, the budget and the flag that sets it.
//
// The client is who the coordinator can tell apart (ClientOf): the subject of a verified TLS
// client certificate, else the peer's IP address without its port. The client token is one
// shared secret for every client, so it names no one; the clients of one host share one budget.
//
// Set with `pf-coordinator --limit NAME=VALUE` (repeatable; SetBudget). The per-job budgets can
// only lower the hard limits of proto/limits.h.

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>

#include <grpcpp/support/server_callback.h>

namespace pf::server {

class Scheduler;
class SceneStore;

struct Budgets {
  // Jobs (SubmitJob): queued + running, per client and in all.
  uint64_t jobs_per_client = 1000;
  uint64_t jobs_total = 4000;
  // Tasks: of one job (at most limits::kMaxTasksPerJob), and in memory: of the queued and running
  // jobs, and of ended ones until their task lists are released (Scheduler::Load). A task costs
  // the coordinator ~440 bytes (docs/farm.md "Coordinator memory").
  uint64_t tasks_per_job = uint64_t(1) << 20;
  uint64_t tasks_total = uint64_t(2) << 20;
  // Pixels (width × height): of one job (at most kMaxImagePixels), and of all jobs counted as for
  // tasks_total (a job's accumulator is 47 bytes per pixel once its first result is merged).
  uint64_t pixels_per_job = uint64_t(4096) * 4096;
  uint64_t pixels_total = uint64_t(1) << 28;
  // WatchJob streams open, per client and in all; a stream whose client has not taken an
  // update for this long is ended (server/rpc/watch_hub.h).
  uint64_t watchers_per_client = 64;
  uint64_t watchers_total = 512;
  double watch_unread_seconds = 60;
  // UploadScene: bytes of file content in one request (at most kMaxBundleBytes), uploads in
  // flight (received, waiting for or in the scene load) per client and in all, and the stored
  // scene bundles' bytes in all.
  uint64_t upload_bytes = uint64_t(64) << 20;
  uint64_t uploads_per_client = 2;
  uint64_t uploads_total = 4;
  uint64_t scene_bytes_total = uint64_t(16) << 30;
};

// Sets one budget from "NAME=VALUE" (a --limit flag); InputError naming the flag, the name and
// the rule otherwise: unknown name, not a whole number ≥ 1 (seconds: a positive number), or a
// per-job budget above its hard limit.
void SetBudget(Budgets* budgets, std::string_view assignment);
// "jobs_per_client=1000 jobs_total=4000 …", every budget, for the start-up log line.
std::string DescribeBudgets(const Budgets& budgets);

// The client a call comes from (see above): "cert:" + the verified client certificate's
// subject, else "ipv4:1.2.3.4" / "ipv6:[::1]" (gRPC's peer without the port), else the peer.
std::string ClientOf(const grpc::CallbackServerContext& context);

class Admission;

// What an admitted request holds against the budgets until it is destroyed (moveable).
class Reservation {
 public:
  Reservation() = default;
  Reservation(Reservation&& other) noexcept { *this = std::move(other); }
  Reservation& operator=(Reservation&& other) noexcept;
  Reservation(const Reservation&) = delete;
  Reservation& operator=(const Reservation&) = delete;
  ~Reservation() { Release(); }
  void Release();

 private:
  friend class Admission;
  Reservation(Admission* admission, bool upload, std::string client, uint64_t amount_a, uint64_t amount_b)
      : admission_(admission),
        upload_(upload),
        client_(std::move(client)),
        amount_a_(amount_a),
        amount_b_(amount_b) {}
  Admission* admission_ = nullptr;
  bool upload_ = false;  // else a job
  std::string client_;
  uint64_t amount_a_ = 0, amount_b_ = 0;  // job: tasks, pixels; upload: bytes, —
};

// Checks jobs and uploads against the budgets. Jobs already in the scheduler count through
// Scheduler::Load; a job admitted but not yet added (its rows are being written) holds a
// Reservation, so that concurrent submissions cannot overshoot a budget together. Thread-safe.
class Admission {
 public:
  Admission(const Budgets& budgets, Scheduler& scheduler, SceneStore& scenes)
      : budgets_(budgets), scheduler_(scheduler), scenes_(scenes) {}

  const Budgets& budgets() const { return budgets_; }
  // A job of `tasks` scheduled tasks and `pixels` pixels from `client`: a reservation to drop
  // once the job is in the scheduler, or LimitError (field spec, spec.plan or spec.camera).
  Reservation AdmitJob(const std::string& client, uint64_t tasks, uint64_t pixels);
  // An UploadScene of `bytes` bytes of file content from `client`, on the gRPC thread before the
  // request is queued: its size and the uploads in flight (LimitError, field bundle.files or
  // bundle). The reservation counts the upload and its bytes until it is dropped.
  Reservation AdmitUpload(const std::string& client, uint64_t bytes);
  // Before the scene is written and loaded: the stored scene bytes with this upload's (and those of
  // the other uploads in flight) within scene_bytes_total, unless `already_stored` (asked only
  // then) says that the bundle is stored — storing it again costs nothing. LimitError otherwise.
  void CheckSceneBytes(const Reservation& upload, const std::function<bool()>& already_stored);

 private:
  friend class Reservation;
  void Release(const Reservation& r);

  const Budgets budgets_;
  Scheduler& scheduler_;
  SceneStore& scenes_;
  std::mutex mu_;
  // Admitted jobs not yet in the scheduler.
  uint64_t pending_jobs_ = 0, pending_tasks_ = 0, pending_pixels_ = 0;
  std::map<std::string, uint64_t> pending_client_jobs_;
  // Uploads in flight and the bytes they may add to the stored scenes.
  uint64_t uploads_ = 0, upload_bytes_ = 0;
  std::map<std::string, uint64_t> client_uploads_;
};

}  // namespace pf::server
