// pf_fake_worker — a test and benchmark client that speaks WorkerService directly, mostly without
// rendering. Modes:
//   bad-size   lease one task, complete it with one pixel too few        (e2e: must be rejected)
//   nan        lease one task, complete it with a NaN in the first pixel (e2e: must be rejected)
//   negative   lease one task, complete it with -1e9 in the first pixel  (e2e: must be rejected)
//   huge       lease one task, complete it with 1e9 in the first pixel   (e2e: in the accumulator's
//              range, but above the job's plausibility bound: rejected unless another worker
//              (--worker-id) sends the same bytes)
//   flaky      for --seconds, lease tasks and answer each at once with FailTask(retryable) (a
//              worker whose every task fails in milliseconds); prints leases and failures
//   instant    lease and complete (zeros of the right size) as fast as possible with
//              --concurrency threads, each with its own connection, until --tasks results were
//              merged or --seconds passed; prints completions/s and bytes on the wire per task
//              (bench/farm_bench.sh: the coordinator alone, "instant workers")
//   scale      a malicious worker (docs/farm.md "Result verification"): pf-worker's own loop
//              (worker/worker.h) renders every task honestly, then multiplies every value of the
//              result by --factor (1.5, 1000, 0) before sending it, for --seconds
//   shift-photons  the same for map pieces: traces a piece honestly, then moves the last quarter of
//              each photon list (past the first 4096 photons the coordinator always checks) by a
//              millimetre, re-serialized with fresh checksums; render tasks are honest
//   hijack     a lease hijack (docs/security.md, "Leases are bound to their worker"): leases a task
//              or map piece as an accomplice (--worker-id + "-accomplice", the holder whose lease id
//              leaked), then presents that lease as --worker-id: ExtendLease, CompleteTask (zeros)
//              or UploadPhotonChunk (an empty piece), FailTask(retryable = false); then the
//              accomplice hands the lease back (FailTask, retryable) and the attacker asks for work
//              again. Exit 0 if every call of the attacker was refused with PERMISSION_DENIED
// Prints one JSON object on stdout. Exit 0 if the mode did what it was asked, 1 otherwise.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "common/core/sha256.h"
#include "common/photon/photon_chunk.h"
#include "common/plan/task_plan.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "rpc/grpc_channel.h"
#include "worker/worker.h"

namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

namespace {

struct Options {
  std::string coordinator, token, mode = "instant", worker_id, cache_dir = "fake-worker-cache";
  double wait = 5, seconds = 10, factor = 1.5;
  uint64_t tasks = 1000;
  int concurrency = 4;
};

uint64_t PixelsOfTask(const v1::Task& t) {
  const pf::CameraSpec cam = pf::CameraFromProto(t.camera(), "task.camera");
  return pf::CountPixels(pf::PixelSubsetFromProto(t.pixels(), "task.pixels"), cam.width, cam.height);
}

std::string WorkerId(const Options& o) {
  return o.worker_id.empty() ? "fake-" + o.mode : o.worker_id;
}

// A context for one call: the token and a deadline of 10 s.
std::unique_ptr<grpc::ClientContext> CallContext(const Options& o) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  pf::PrepareContext(ctx.get(), o.token, std::chrono::seconds(10));
  return ctx;
}

// FailTask of `task`'s lease in the name of `worker_id`.
grpc::Status FailLease(v1::WorkerService::Stub& stub, const Options& o, const v1::Task& task,
                       const std::string& worker_id, const std::string& reason, bool retryable) {
  v1::FailTaskRequest req;
  req.set_lease_id(task.lease_id());
  req.set_worker_id(worker_id);
  req.set_reason(reason);
  req.set_retryable(retryable);
  v1::FailTaskResponse resp;
  return stub.FailTask(CallContext(o).get(), req, &resp);
}

bool LeaseOne(v1::WorkerService::Stub& stub, const Options& o, double wait, v1::Task* task,
              grpc::Status* status) {
  v1::LeaseTaskRequest req;
  req.set_worker_id(WorkerId(o));
  req.set_worker_version(PF_VERSION);
  req.set_threads(1);
  req.set_wait_seconds(wait);
  grpc::ClientContext ctx;
  pf::PrepareContext(&ctx, o.token, pf::Seconds(wait + 10));
  v1::LeaseTaskResponse resp;
  *status = stub.LeaseTask(&ctx, req, &resp);
  if (!status->ok() || !resp.has_task()) return false;
  *task = resp.task();
  return true;
}

int BadResult(const Options& o) {
  auto stub = v1::WorkerService::NewStub(pf::MakeCoordinatorChannel(o.coordinator, {}));
  v1::Task task;
  grpc::Status st;
  if (!LeaseOne(*stub, o, o.wait, &task, &st)) {
    std::printf(
        "%s\n",
        nlohmann::json{{"error", "no task leased"}, {"status", pf::StatusToString(st)}}.dump().c_str());
    return 1;
  }
  const uint64_t pixels = PixelsOfTask(task);
  v1::CompleteTaskRequest req;
  req.set_lease_id(task.lease_id());
  req.set_worker_id(WorkerId(o));
  req.set_part(task.part());  // as a real worker echoes it
  const uint64_t n = o.mode == "bad-size" ? (pixels - 1) * 3 : pixels * 3;
  for (uint64_t i = 0; i < n; ++i) req.add_rgb_sums(0.25f);
  if (o.mode == "nan") req.set_rgb_sums(0, std::numeric_limits<float>::quiet_NaN());
  if (o.mode == "negative") req.set_rgb_sums(0, -1e9f);
  if (o.mode == "huge") req.set_rgb_sums(0, 1e9f);
  v1::CompleteTaskResponse resp;
  const grpc::Status s = stub->CompleteTask(CallContext(o).get(), req, &resp);
  std::printf("%s\n", nlohmann::json{{"job_id", task.job_id()},
                                     {"task_id", task.task_id()},
                                     {"attempt", task.attempt()},
                                     {"pixels", pixels},
                                     {"code", pf::StatusCodeName(s.error_code())},
                                     {"message", s.error_message()},
                                     {"merged", resp.merged()}}
                          .dump()
                          .c_str());
  return s.ok() ? 1 : 0;
}

int Flaky(const Options& o) {
  auto stub = v1::WorkerService::NewStub(pf::MakeCoordinatorChannel(o.coordinator, {}));
  uint64_t leases = 0, failures = 0;
  std::string error;
  const Clock::time_point until = Clock::now() + pf::Seconds(o.seconds);
  while (Clock::now() < until) {
    v1::Task task;
    grpc::Status st;
    if (!LeaseOne(*stub, o, 0.5, &task, &st)) {
      if (!st.ok()) error = pf::StatusToString(st);
      continue;
    }
    ++leases;
    const grpc::Status s =
        FailLease(*stub, o, task, WorkerId(o), "simulated failure (pf_fake_worker --mode flaky)", true);
    if (s.ok())
      ++failures;
    else
      error = pf::StatusToString(s);
  }
  std::printf("%s\n",
              nlohmann::json{{"mode", "flaky"}, {"leases", leases}, {"failures", failures}, {"error", error}}
                  .dump()
                  .c_str());
  return failures > 0 ? 0 : 1;
}

int Instant(const Options& o) {
  std::atomic<uint64_t> merged{0}, completed{0}, leases{0}, bytes{0}, pixels{0}, task_bytes{0};
  std::atomic<bool> stop{false};
  std::mutex error_mutex;
  std::string error;
  const Clock::time_point t0 = Clock::now();
  const Clock::time_point until = t0 + pf::Seconds(o.seconds);
  std::vector<std::thread> threads;
  for (int i = 0; i < o.concurrency; ++i)
    threads.emplace_back([&] {
      auto stub = v1::WorkerService::NewStub(pf::MakeCoordinatorChannel(o.coordinator, {}));
      v1::CompleteTaskRequest req;
      while (!stop && Clock::now() < until) {
        v1::Task task;
        grpc::Status st;
        if (!LeaseOne(*stub, o, 0.2, &task, &st)) {
          if (!st.ok()) {
            std::lock_guard lock(error_mutex);
            error = pf::StatusToString(st);
            stop = true;
          }
          continue;
        }
        ++leases;
        task_bytes += task.ByteSizeLong();
        const uint64_t n = PixelsOfTask(task);
        req.Clear();
        req.set_lease_id(task.lease_id());
        req.set_worker_id(WorkerId(o));
        req.set_part(task.part());
        req.mutable_rgb_sums()->Resize(int(n * 3), 0.0f);
        v1::CompleteTaskResponse resp;
        const grpc::Status s = stub->CompleteTask(CallContext(o).get(), req, &resp);
        if (!s.ok()) {
          std::lock_guard lock(error_mutex);
          error = pf::StatusToString(s);
          continue;
        }
        ++completed;
        bytes += req.ByteSizeLong();
        pixels += n;
        if (resp.merged() && ++merged >= o.tasks) stop = true;
      }
    });
  for (std::thread& t : threads) t.join();
  const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  const uint64_t c = completed.load();
  nlohmann::json j = {
      {"mode", "instant"},
      {"concurrency", o.concurrency},
      {"leases", leases.load()},
      {"completed", c},
      {"merged", merged.load()},
      {"seconds", seconds},
      {"completions_per_second", c / seconds},
      {"result_bytes_per_task", c ? double(bytes.load()) / double(c) : 0.0},
      {"task_bytes_per_lease", leases ? double(task_bytes.load()) / double(leases.load()) : 0.0},
      {"pixels_per_task", c ? double(pixels.load()) / double(c) : 0.0},
      {"error", error}};
  std::printf("%s\n", j.dump().c_str());
  return merged.load() > 0 ? 0 : 1;
}

// Moves the photons of the last quarter of every list: beyond the prefix the coordinator traces for
// every piece, in a piece of more than 4096 photons.
void ShiftPhotons(std::string& bytes) {
  pf::PhotonChunk chunk = pf::DeserializePhotonChunk(bytes);
  for (pf::PhotonChunk::List& list : chunk.lists)
    for (size_t i = list.photons.size() - list.photons.size() / 4; i < list.photons.size(); ++i)
      list.photons[i].position[0] += 1e-3f;
  bytes = pf::SerializePhotonChunk(chunk);
}

// Honest renders and traces, dishonest results: scales every result's sums (`scale`) or shifts
// photons of every traced piece (`shift-photons`).
class Tampering : public pf::worker::WorkerFaults {
 public:
  Tampering(bool scale, float factor) : scale_(scale), factor_(factor) {}
  void OnResult(std::vector<float>& sums) override {
    if (!scale_) return;
    for (float& v : sums) v *= factor_;
    ++tampered;
  }
  void OnPiece(std::string& bytes) override {
    if (scale_) return;
    ShiftPhotons(bytes);
    ++tampered;
  }
  std::atomic<uint64_t> tampered{0};

 private:
  bool scale_;
  float factor_;
};

// pf-worker's loop with injected tampering: honest renders and traces, dishonest results.
int Malicious(const Options& o) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("pf_fake_worker"));  // stdout is the JSON
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ [pf_fake_worker] %v");
  pf::worker::WorkerOptions w;
  w.coordinator = o.coordinator;
  w.token = o.token;
  w.worker_id = WorkerId(o);
  w.threads = 1;
  w.cache_dir = o.cache_dir;
  w.poll_seconds = 1;
  auto faults = std::make_shared<Tampering>(o.mode == "scale", float(o.factor));
  w.faults = faults;
  pf::worker::Worker worker(w);
  std::thread stopper([&] {
    std::this_thread::sleep_for(pf::Seconds(o.seconds));
    worker.RequestAbort();
  });
  const int code = worker.Run();
  stopper.join();
  const pf::worker::WorkerCounters c = worker.counters();
  std::printf("%s\n", nlohmann::json{{"mode", o.mode},
                                     {"factor", o.factor},
                                     {"leased", c.leased},
                                     {"completed", c.completed},
                                     {"merged", c.merged},
                                     {"chunks_traced", c.chunks_traced},
                                     {"tampered", faults->tampered.load()},
                                     {"exit", code}}
                          .dump()
                          .c_str());
  std::fflush(stdout);
  // A render may still run on its thread (render_in_flight): end without waiting for it.
  std::_Exit(faults->tampered > 0 ? 0 : 1);
}

// A leaked lease put to use by another worker: every call must be refused, and nothing of the
// attacker's may be taken.
int Hijack(const Options& o) {
  auto stub = v1::WorkerService::NewStub(pf::MakeCoordinatorChannel(o.coordinator, {}));
  Options accomplice = o;
  accomplice.worker_id = WorkerId(o) + "-accomplice";
  v1::Task task;
  grpc::Status st;
  const Clock::time_point until = Clock::now() + pf::Seconds(o.seconds);
  while (!LeaseOne(*stub, accomplice, 1, &task, &st))
    if (Clock::now() > until) {
      std::printf(
          "%s\n",
          nlohmann::json{{"error", "no task leased"}, {"status", pf::StatusToString(st)}}.dump().c_str());
      return 1;
    }
  const bool piece = task.has_trace_chunk();
  std::fprintf(stderr, "leased-%s job=%s\n", piece ? "piece" : "task", task.job_id().c_str());
  nlohmann::json calls;
  {
    v1::ExtendLeaseRequest req;
    req.set_lease_id(task.lease_id());
    req.set_worker_id(WorkerId(o));
    req.set_progress(0.5);
    v1::ExtendLeaseResponse resp;
    calls["ExtendLease"] = pf::StatusToString(stub->ExtendLease(CallContext(o).get(), req, &resp));
  }
  if (piece) {
    pf::PhotonChunk empty;
    empty.begin = task.trace_chunk().photon_begin();
    empty.end = task.trace_chunk().photon_end();
    const std::string bytes = pf::SerializePhotonChunk(empty);
    v1::UploadPhotonChunkResponse resp;
    auto c = CallContext(o);
    std::unique_ptr<grpc::ClientWriter<v1::PhotonChunkPart>> writer(stub->UploadPhotonChunk(c.get(), &resp));
    v1::PhotonChunkPart part;
    part.set_lease_id(task.lease_id());
    part.set_worker_id(WorkerId(o));
    part.set_total_bytes(bytes.size());
    part.set_digest(pf::Sha256Hex(bytes));
    part.set_offset(0);
    part.set_data(bytes);
    part.set_sha256(pf::Sha256Hex(bytes));
    writer->Write(part);
    writer->WritesDone();
    calls["UploadPhotonChunk"] = pf::StatusToString(writer->Finish());
  } else {
    v1::CompleteTaskRequest req;
    req.set_lease_id(task.lease_id());
    req.set_worker_id(WorkerId(o));
    for (uint64_t i = 0, n = PixelsOfTask(task) * 3; i < n; ++i) req.add_rgb_sums(0);
    v1::CompleteTaskResponse resp;
    calls["CompleteTask"] = pf::StatusToString(stub->CompleteTask(CallContext(o).get(), req, &resp));
  }
  calls["FailTask"] =
      pf::StatusToString(FailLease(*stub, o, task, WorkerId(o), "hijack: end the job", false));
  // The accomplice hands the lease back, so that an honest worker takes it without waiting.
  calls["accomplice FailTask"] = pf::StatusToString(
      FailLease(*stub, o, task, accomplice.worker_id, "handed back (pf_fake_worker --mode hijack)", true));
  bool refused = true;
  for (const auto& [call, status] : calls.items())
    if (call.rfind("accomplice", 0) != 0)
      refused = refused && status.get<std::string>().rfind("PERMISSION_DENIED", 0) == 0;
  std::printf("%s\n",
              nlohmann::json{{"mode", "hijack"}, {"piece", piece}, {"calls", calls}, {"refused", refused}}
                  .dump()
                  .c_str());
  return refused ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  std::string token_file;
  CLI::App app{"pf_fake_worker: speaks WorkerService without rendering (tests and benchmarks)"};
  app.add_option("--coordinator", o.coordinator, "HOST:PORT")->required();
  app.add_option("--token-file", token_file, "Bearer token file (default $PF_TOKEN)");
  app.add_option("--mode", o.mode,
                 "bad-size | nan | negative | huge | flaky | instant | scale | shift-photons | hijack")
      ->check(CLI::IsMember(
          {"bad-size", "nan", "negative", "huge", "flaky", "instant", "scale", "shift-photons", "hijack"}));
  app.add_option("--factor", o.factor, "scale: every value of a result is multiplied by this")
      ->capture_default_str();
  app.add_option("--cache-dir", o.cache_dir, "scale, shift-photons: the worker's scene cache")
      ->capture_default_str();
  app.add_option("--worker-id", o.worker_id, "worker_id in LeaseTask (default fake-MODE)");
  app.add_option("--wait", o.wait, "bad-size/nan/negative/huge: seconds to wait for a task")
      ->capture_default_str();
  app.add_option("--tasks", o.tasks, "instant: stop after this many merged results")->capture_default_str();
  app.add_option("--seconds", o.seconds, "flaky, instant, scale, shift-photons, hijack: stop after this long")
      ->capture_default_str();
  app.add_option("--concurrency", o.concurrency, "instant: parallel fake workers")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    o.token = pf::ResolveToken(token_file);
    if (o.mode == "instant") return Instant(o);
    if (o.mode == "flaky") return Flaky(o);
    if (o.mode == "scale" || o.mode == "shift-photons") return Malicious(o);
    if (o.mode == "hijack") return Hijack(o);
    return BadResult(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pf_fake_worker: %s\n", e.what());
    return 1;
  }
}
