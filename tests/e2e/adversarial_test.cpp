// A property test that throws random, well-formed but adversarial requests at a live
// pf-coordinator process — SubmitJob specs with boundary and absurd values, LeaseTask with odd
// worker ids and waits, CompleteTask with wrong sizes / NaN / negative / huge sums for real and
// forged leases, ExtendLease, CompleteTask and FailTask with other workers' leases or no worker id,
// WatchJob with odd rates,
// GetJob/CancelJob/ListJobs with forged ids and page tokens, and undecodable request bytes.
//
// Properties, for a fixed seed (deterministic sequence of requests):
//   - every call returns a status within its deadline plus a small slack (nothing hangs);
//   - no call answers UNKNOWN, INTERNAL (except undecodable bytes, which gRPC itself rejects
//     before any handler), DATA_LOSS or UNIMPLEMENTED: every refusal is a deliberate one;
//   - afterwards the coordinator is alive and answers, and a normal job rendered by a real
//     worker is bit-identical to the same job rendered locally.
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <map>
#include <mutex>
#include <random>
#include <set>

#include "client/farm_client.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "rpc/grpc_channel.h"
#include "tests/e2e/harness.h"
#include "tests/util/generic_call.h"

namespace pf::e2e {
namespace {
namespace v1 = photonfarm::v1;
using SteadyClock = std::chrono::steady_clock;

class Adversary {
 public:
  Adversary(const std::string& address, uint64_t seed)
      : channel_(MakeCoordinatorChannel(address, {})),
        render_(v1::RenderService::NewStub(channel_)),
        worker_(v1::WorkerService::NewStub(channel_)),
        generic_(channel_),
        rng_(seed) {}

  // A random request of a random kind; records its status code and checks its duration.
  void Step() {
    switch (Pick(12)) {
      case 0:
      case 1:
        SubmitJob();
        break;
      case 2:
      case 3:
        LeaseTask();
        break;
      case 4:
      case 5:
        CompleteTask();
        break;
      case 6:
        ExtendLease();
        break;
      case 7:
        FailTask();
        break;
      case 8:
        WatchJob();
        break;
      case 9:
        JobCalls();
        break;
      case 10:
        ListJobs();
        break;
      case 11:
        RawBytes();
        break;
    }
  }

  const std::map<std::string, std::map<std::string, int>>& codes() const { return codes_; }
  std::vector<std::string> failures;
  double slowest_excess = 0;  // seconds beyond a call's deadline, worst case

 private:
  uint64_t Pick(uint64_t n) { return std::uniform_int_distribution<uint64_t>(0, n - 1)(rng_); }
  template <typename T>
  T OneOf(std::initializer_list<T> values) {
    return *(values.begin() + Pick(values.size()));
  }
  bool Coin() { return Pick(2) == 0; }

  // Arbitrary bytes (only for RawBytes: proto3 strings must be UTF-8, gRPC refuses others).
  std::string RandomBytes(size_t max_len) {
    std::string s(Pick(max_len + 1), '\0');
    for (char& c : s) c = char(Pick(256));
    return s;
  }
  // Hostile but valid UTF-8: NUL and control bytes, ESC sequences, quotes, backslashes,
  // right-to-left override, non-ASCII letters.
  std::string RandomText(size_t max_len) {
    static const char* kPieces[] = {
        "\x1b[2J", "\n[error] forged", "\r", "'", "\\", "\u202e", "\u00e9", "%s%n", "../", " ", "job-", "x"};
    std::string s;
    const size_t len = Pick(max_len + 1);
    while (s.size() < len) {
      if (Pick(3) == 0)
        s += char(Pick(0x80));
      else
        s += kPieces[Pick(std::size(kPieces))];
    }
    return s;
  }
  std::string RandomId() {
    switch (Pick(6)) {
      case 0:
        return "";
      case 1:
        return RandomText(40);
      case 2:
        return std::string(Pick(3) == 0 ? 1 << 20 : 129, 'x');
      case 3:
        return jobs_.empty() ? "job-0" : jobs_[Pick(jobs_.size())];
      case 4:
        return leases_.empty() ? "lease" : leases_[Pick(leases_.size())].lease_id();
      default:
        return "job-" + std::to_string(Pick(1000000));
    }
  }
  double RandomSeconds() {
    return OneOf<double>({0.0, 0.01, 0.2, -1.0, std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::infinity(), 1e300, -0.0});
  }

  std::unique_ptr<grpc::ClientContext> Ctx(double seconds) {
    auto ctx = std::make_unique<grpc::ClientContext>();
    ctx->set_deadline(std::chrono::system_clock::now() + Seconds(seconds));
    return ctx;
  }

  // Every call goes through here: its duration is bounded by its deadline plus a slack.
  template <typename F>
  void Call(const std::string& rpc, double deadline, F&& f) {
    const auto t0 = SteadyClock::now();
    const grpc::Status st = f(Ctx(deadline));
    const double took = std::chrono::duration<double>(SteadyClock::now() - t0).count();
    slowest_excess = std::max(slowest_excess, took - deadline);
    if (took > deadline + 2.0)
      failures.push_back(rpc + " took " + std::to_string(took) + " s (deadline " + std::to_string(deadline) +
                         ")");
    const auto code = st.error_code();
    ++codes_[rpc][StatusCodeName(code)];
    // Undecodable bytes are refused by gRPC itself before any handler runs (this gRPC answers
    // UNIMPLEMENTED or INTERNAL); everything else must be a deliberate answer of ours.
    const bool raw = rpc.rfind("raw ", 0) == 0;
    const bool grpc_refusal = code == grpc::StatusCode::UNIMPLEMENTED || code == grpc::StatusCode::INTERNAL;
    if (code == grpc::StatusCode::UNKNOWN || code == grpc::StatusCode::DATA_LOSS || (grpc_refusal && !raw))
      failures.push_back(rpc + " answered " + StatusToString(st));
  }

  v1::JobSpec RandomSpec() {
    v1::JobSpec spec;
    if (Pick(8) == 0) spec.set_name(RandomText(300));
    spec.set_scene_hash(Pick(6) == 0 ? RandomId() : (Pick(8) == 0 ? std::string(64, 'a') : scene_hash_));
    if (Coin()) {
      v1::Camera* cam = spec.mutable_camera();
      const double big = 1e30, nan = std::numeric_limits<double>::quiet_NaN();
      cam->set_width(OneOf<uint32_t>({0, 1, 16, 33, 9000}));
      cam->set_height(OneOf<uint32_t>({0, 1, 16, 33, 4294967295u}));
      if (Coin()) {
        cam->mutable_eye()->set_z(OneOf<double>({3.9, 0, nan, big}));
        cam->mutable_look_at()->set_y(OneOf<double>({1, 0, -big}));
        cam->mutable_up()->set_y(OneOf<double>({1, 0, nan}));
        cam->set_vfov_degrees(OneOf<double>({39.3, 0, 1e-300, 179.9999999, 180, -5, nan}));
      }
    }
    v1::RenderSettings* s = spec.mutable_settings();
    s->set_integrator(OneOf<v1::Integrator>(
        {v1::INTEGRATOR_PHOTONMAP, v1::INTEGRATOR_PATH, v1::INTEGRATOR_UNSPECIFIED, v1::Integrator(77)}));
    s->mutable_photon_map()->set_photons(OneOf<uint64_t>({0, 1, 1000, uint64_t(1) << 40}));
    s->mutable_photon_map()->set_k(OneOf<uint32_t>({0, 1, 20, 4000000000u}));
    switch (Pick(4)) {
      case 0:
        spec.mutable_plan()->mutable_skipping()->set_stride(OneOf<uint32_t>({0, 1, 2, 3, 40, 4294967295u}));
        spec.mutable_plan()->mutable_skipping()->set_rounds(OneOf<uint32_t>({0, 1, 2, 3, 4294967295u}));
        spec.mutable_plan()->mutable_skipping()->set_samples_per_pixel(OneOf<uint32_t>({0, 1, 2, 70000}));
        break;
      case 1:
        spec.mutable_plan()->mutable_multiple_maps()->set_maps(OneOf<uint32_t>({0, 1, 3, 5000, 4294967295u}));
        spec.mutable_plan()->mutable_multiple_maps()->set_tile_size(OneOf<uint32_t>({0, 1, 5, 4096}));
        spec.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(OneOf<uint32_t>({0, 1, 70000}));
        break;
      case 2:
        spec.mutable_plan()->mutable_maps_in_turn()->set_samples_per_pixel(OneOf<uint32_t>({0, 1, 2, 70000}));
        spec.mutable_plan()->mutable_maps_in_turn()->set_tile_size(OneOf<uint32_t>({0, 1, 7}));
        break;
      default:
        break;  // no plan
    }
    spec.set_seed(Pick(1000));
    spec.set_priority(OneOf<int32_t>({0, -1, 1, std::numeric_limits<int32_t>::min()}));
    if (Coin()) spec.mutable_stop()->set_time_budget_seconds(RandomSeconds());
    if (Coin()) spec.mutable_stop()->set_target_noise_rms(RandomSeconds());
    if (Coin()) spec.mutable_stop()->set_max_rounds(OneOf<uint32_t>({0, 1, 4294967295u}));
    return spec;
  }

  void SubmitJob() {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = RandomSpec();
    v1::SubmitJobResponse resp;
    Call("SubmitJob", 10, [&](auto ctx) {
      grpc::Status st = render_->SubmitJob(ctx.get(), req, &resp);
      if (st.ok()) jobs_.push_back(resp.job_id());
      return st;
    });
  }

  void LeaseTask() {
    v1::LeaseTaskRequest req;
    req.set_worker_id(Pick(4) == 0 ? RandomId() : "adversary-" + std::to_string(Pick(3)));
    req.set_wait_seconds(RandomSeconds());
    // Mostly the coordinator's build; else another build or none (FAILED_PRECONDITION), or junk
    // that is no version string at all (INVALID_ARGUMENT).
    req.set_worker_version(Pick(4) != 0 ? std::string(PF_VERSION) : Coin() ? RandomId() : std::string());
    req.set_threads(OneOf<uint32_t>({0, 1, 4294967295u}));
    for (int i = 0; i < int(Pick(3)); ++i) req.add_cached_map_seeds(rng_());
    v1::LeaseTaskResponse resp;
    // A long poll may wait up to 30 s: the client gives up first (DEADLINE_EXCEEDED is an answer).
    Call("LeaseTask", 0.3, [&](auto ctx) {
      grpc::Status st = worker_->LeaseTask(ctx.get(), req, &resp);
      if (st.ok() && resp.has_task()) {
        leases_.push_back(resp.task());
        lease_worker_[resp.task().lease_id()] = req.worker_id();
      }
      return st;
    });
  }

  void CompleteTask() {
    v1::CompleteTaskRequest req;
    uint64_t pixels = 1;
    if (!leases_.empty() && Pick(4) != 0) {
      const v1::Task& t = leases_[Pick(leases_.size())];
      req.set_lease_id(t.lease_id());
      req.set_worker_id(WorkerFor(t.lease_id()));
      try {
        const CameraSpec cam = CameraFromProto(t.camera(), "camera");
        pixels = CountPixels(PixelSubsetFromProto(t.pixels(), "pixels"), cam.width, cam.height);
      } catch (const std::exception&) {
      }
    } else {
      req.set_lease_id(RandomId());
      req.set_worker_id(RandomId());
    }
    uint64_t n = 3 * pixels;
    if (Pick(3) == 0) n = OneOf<uint64_t>({0, 2, n + 3, n - 3});
    n = std::min<uint64_t>(n, 1 << 20);
    const float value = OneOf<float>({0.5f, 0.0f, -1.0f, 1e9f, 1e30f, std::numeric_limits<float>::quiet_NaN(),
                                      std::numeric_limits<float>::infinity(), -0.0f});
    req.mutable_rgb_sums()->Resize(int(n), 0.25f);
    if (n > 0) req.set_rgb_sums(int(Pick(n)), value);
    v1::CompleteTaskResponse resp;
    Call("CompleteTask", 10, [&](auto ctx) { return worker_->CompleteTask(ctx.get(), req, &resp); });
  }

  // Mostly the lease's holder; else a stranger (PERMISSION_DENIED) or none (INVALID_ARGUMENT).
  std::string WorkerFor(const std::string& lease_id) {
    const auto holder = lease_worker_.find(lease_id);
    if (holder != lease_worker_.end() && Pick(4) != 0) return holder->second;
    return Coin() ? RandomId() : std::string();
  }

  void ExtendLease() {
    v1::ExtendLeaseRequest req;
    req.set_lease_id(!leases_.empty() && Coin() ? leases_[Pick(leases_.size())].lease_id() : RandomId());
    req.set_worker_id(WorkerFor(req.lease_id()));
    req.set_progress(RandomSeconds());
    v1::ExtendLeaseResponse resp;
    Call("ExtendLease", 5, [&](auto ctx) { return worker_->ExtendLease(ctx.get(), req, &resp); });
  }

  void FailTask() {
    v1::FailTaskRequest req;
    req.set_lease_id(RandomId());
    // Mostly not the holder: a stranger must never fail a job.
    const auto holder = lease_worker_.find(req.lease_id());
    req.set_worker_id(holder != lease_worker_.end() && Pick(4) == 0 ? holder->second : RandomId());
    req.set_reason(RandomText(Pick(10) == 0 ? 10000 : 50));
    req.set_retryable(Coin());
    v1::FailTaskResponse resp;
    Call("FailTask", 5, [&](auto ctx) { return worker_->FailTask(ctx.get(), req, &resp); });
  }

  void WatchJob() {
    v1::WatchJobRequest req;
    req.set_job_id(RandomId());
    req.set_include_images(Coin());
    req.set_min_interval_seconds(RandomSeconds());
    Call("WatchJob", 1.0, [&](auto ctx) {
      auto reader = render_->WatchJob(ctx.get(), req);
      v1::JobUpdate update;
      for (int i = 0; i < 2 && reader->Read(&update); ++i) {
      }
      ctx->TryCancel();
      while (reader->Read(&update)) {
      }
      grpc::Status st = reader->Finish();
      // Cancelled by us after two updates: a normal end of a watch.
      return st.error_code() == grpc::StatusCode::CANCELLED ? grpc::Status::OK : st;
    });
  }

  // A unary RenderService call (`rpc`, 5 s deadline) whose request names job `id`.
  template <typename Request, typename Response>
  void UnaryJobCall(const std::string& rpc, const std::string& id,
                    grpc::Status (v1::RenderService::Stub::*method)(grpc::ClientContext*, const Request&,
                                                                    Response*)) {
    Request req;
    req.set_job_id(id);
    Response resp;
    Call(rpc, 5, [&](auto ctx) { return (render_.get()->*method)(ctx.get(), req, &resp); });
  }

  void JobCalls() {
    const std::string id = RandomId();
    switch (Pick(4)) {
      case 0:
        UnaryJobCall("GetJob", id, &v1::RenderService::Stub::GetJob);
        break;
      case 1:
        UnaryJobCall("CancelJob", id, &v1::RenderService::Stub::CancelJob);
        break;
      case 2:
        UnaryJobCall("ListJobEvents", id, &v1::RenderService::Stub::ListJobEvents);
        break;
      default: {
        v1::GetImageRequest req;
        req.set_job_id(id);
        Call("GetImage", 5, [&](auto ctx) {
          auto reader = render_->GetImage(ctx.get(), req);
          v1::ImageChunk chunk;
          while (reader->Read(&chunk)) {
          }
          return reader->Finish();
        });
      }
    }
  }

  void ListJobs() {
    v1::ListJobsRequest req;
    req.set_include_finished(Coin());
    req.set_page_size(OneOf<uint32_t>({0, 1, 2, 4294967295u}));
    if (Coin()) req.set_page_token(Pick(3) == 0 ? "p1." + std::to_string(Pick(50) + 1) : RandomId());
    v1::ListJobsResponse resp;
    Call("ListJobs", 5, [&](auto ctx) { return render_->ListJobs(ctx.get(), req, &resp); });
  }

  // Bytes that are not (or only by chance) a valid message, to any unary method.
  void RawBytes() {
    static const char* kMethods[] = {
        "/photonfarm.v1.RenderService/SubmitJob", "/photonfarm.v1.RenderService/GetJob",
        "/photonfarm.v1.RenderService/ListJobs",  "/photonfarm.v1.WorkerService/LeaseTask",
        "/photonfarm.v1.WorkerService/FailTask",  "/photonfarm.v1.WorkerService/CompleteTask"};
    const std::string method = kMethods[Pick(std::size(kMethods))];
    // An empty payload is a valid (empty) message: it must reach the handler (proving that the
    // raw path works); other bytes are mostly undecodable.
    const bool empty = Pick(4) == 0;
    const std::string bytes = empty ? "" : RandomBytes(200);
    Call((empty ? "empty " : "raw ") + method, 0.5, [&](auto ctx) {
      grpc::Slice slice(bytes);
      grpc::ByteBuffer request(&slice, 1), response;
      return test_util::BlockingGenericCall(generic_, ctx.get(), method, &request, &response);
    });
  }

 public:
  std::string scene_hash_;

 private:
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::RenderService::Stub> render_;
  std::unique_ptr<v1::WorkerService::Stub> worker_;
  grpc::GenericStub generic_;
  std::mt19937_64 rng_;
  std::vector<std::string> jobs_;
  std::vector<v1::Task> leases_;
  std::map<std::string, std::string> lease_worker_;
  std::map<std::string, std::map<std::string, int>> codes_;
};

TEST(Adversarial, RandomRequestsGetAStatusInBoundedTimeAndTheCoordinatorStaysCorrect) {
  TestDir dir;
  JobArgs job;
  job.rounds = 1;
  const RunResult local = RenderLocally(dir, job.ToFlags());
  ASSERT_EQ(local.exit_code, 0) << local.err;
  CoordinatorProcess coordinator(dir / "data", dir.path(), {"--lease-seconds", "2"});
  FarmClient client(coordinator.address(), "");
  const std::string hash = client.UploadScene(CollectBundle(Binaries::Scene())).scene_hash();

  Adversary adversary(coordinator.address(), /*seed=*/20261125);
  adversary.scene_hash_ = hash;
  const auto t0 = SteadyClock::now();
  int steps = 0;
  // A fixed number of requests, and a time cap so that a slow machine stays within ~20 s.
  for (; steps < 1500 && SteadyClock::now() - t0 < std::chrono::seconds(12); ++steps) adversary.Step();
  const double seconds = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  std::string summary;
  for (const auto& [rpc, codes] : adversary.codes()) {
    summary += rpc + ":";
    for (const auto& [code, n] : codes) summary += " " + code + "=" + std::to_string(n);
    summary += "\n";
  }
  std::printf("%d adversarial requests in %.2f s (worst excess over a deadline %.3f s)\n%s", steps, seconds,
              adversary.slowest_excess, summary.c_str());
  EXPECT_GE(steps, 300) << "too few requests to mean anything";
  for (const std::string& f : adversary.failures) ADD_FAILURE() << f;
  // Every kind of request was made and some were accepted (the generator is not all garbage).
  EXPECT_GE(adversary.codes().size(), 12u) << summary;
  EXPECT_GT(adversary.codes().at("SubmitJob").count("OK"), 0u) << summary;
  EXPECT_GT(adversary.codes().at("SubmitJob").count("INVALID_ARGUMENT"), 0u) << summary;

  // Still healthy: it answers (every job listed, page by page), and, with the adversary's jobs cancelled, a
  // normal job renders exactly as locally.
  ASSERT_TRUE(coordinator.process().Running());
  const std::vector<v1::JobStatus> all = client.ListJobs(true, 7);
  for (const v1::JobStatus& s : all)
    if (!IsFinalState(s.state())) client.CancelJob(s.job_id());
  RunResult r = RunCommand(Concat(Concat({Binaries::Pf(), "submit", Binaries::Scene()}, job.ToFlags()),
                                  {"--coordinator", coordinator.address()}),
                           dir.path());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const std::string job_id = r.out.substr(0, r.out.find('\n'));
  auto worker = StartWorker(coordinator.address(), dir.path(), "w-after");
  v1::JobStatus st;
  ASSERT_TRUE(WaitUntil([&] { return IsFinalState((st = client.GetJob(job_id)).state()); }, 60));
  ASSERT_EQ(st.state(), v1::JOB_STATE_SUCCEEDED) << st.failure_reason();
  EXPECT_TRUE(BitIdentical(DecodeImage(client.GetImage(job_id)), ReadImage(dir / "local.exr")));
  worker->Signal(SIGTERM);
  EXPECT_EQ(worker->Wait(20).value_or(-1), 0);
}

}  // namespace
}  // namespace pf::e2e
