#pragma once
// Shared helpers of the coordinator tests: temporary data directories, job configs built without
// a scene, synthetic task results, and an in-process coordinator with real gRPC channels.

#include <grpcpp/create_channel.h>
#include <grpcpp/security/credentials.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/core/rng.h"
#include "common/core/sha256.h"
#include "common/plan/task_plan.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "server/clock.h"
#include "server/coordinator.h"
#include "server/jobs/job_spec.h"
#include "server/scheduling/scheduler.h"
#include "server/store/sqlite_store.h"
#include "tests/util/temp_dir.h"

namespace pf::server::testing {

namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// A fresh directory per test, removed afterwards.
class TempDir : public test_util::TempDir {
 public:
  TempDir() : test_util::TempDir("pf_server_test") {}
};

inline JobConfig MakeConfig(const PlanSpec& plan, int width, int height, int32_t priority = 0,
                            StopRule stop = {}) {
  JobConfig c;
  c.scene_hash = std::string(64, 'a');
  c.scene_entry = "scene.mgf";
  c.camera.width = width;
  c.camera.height = height;
  c.plan = plan;
  c.seed = 7;
  c.priority = priority;
  c.stop = stop;
  c.spec.set_scene_hash(c.scene_hash);
  c.spec.set_priority(priority);
  return c;
}

// A deterministic "render" of a task: per pixel and channel, the sum over the task's samples of
// a value that depends on the map (so maps disagree and the noise estimate is > 0).
inline std::vector<float> SyntheticResult(const TaskSpec& task, int width, int height) {
  const std::vector<uint32_t> pixels = PixelsOf(task.pixels, width, height);
  std::vector<float> sums(pixels.size() * 3);
  const uint32_t samples = task.sample_end - task.sample_begin;
  for (size_t i = 0; i < pixels.size(); ++i) {
    Rng rng = Rng::ForKey(HashKey(task.map_seed, pixels[i], 99));
    for (int c = 0; c < 3; ++c) sums[3 * i + c] = float(samples) * (0.5f + 0.25f * c + rng.Uniform());
  }
  return sums;
}

inline PlanSpec Skipping(uint32_t stride, uint32_t rounds, uint32_t spp = 1) {
  return PlanSpec{.kind = PlanKind::kSkipping, .samples_per_pixel = spp, .stride = stride, .rounds = rounds};
}

inline PlanSpec MultipleMaps(uint32_t maps, uint32_t tile, uint32_t spp = 1) {
  return PlanSpec{.kind = PlanKind::kMultipleMaps, .maps = maps, .samples_per_pixel = spp, .tile_size = tile};
}

// A scene catalog that knows one scene, kHash, without files (jobs of it are never rendered).
inline const std::string kHash(64, 'b');
class FakeCatalog final : public SceneCatalog {
 public:
  std::optional<SceneInfo> FindScene(const std::string& hash) const override {
    if (hash != kHash) return std::nullopt;
    SceneInfo info;
    info.hash = kHash;
    info.entry = "scene.mgf";
    info.lights = 1;  // a scene without light is refused (job_spec.h)
    return info;
  }
};

// A 12 x 10 path-traced job of kHash with the skipping plan, 2 samples per pixel.
inline v1::JobSpec SkippingSpec(uint32_t stride, uint32_t rounds) {
  v1::JobSpec spec;
  spec.set_name("crash test");
  spec.set_scene_hash(kHash);
  v1::Camera* cam = spec.mutable_camera();
  cam->mutable_eye()->set_z(5);
  cam->mutable_up()->set_y(1);
  cam->set_vfov_degrees(40);
  cam->set_width(12);
  cam->set_height(10);
  spec.mutable_settings()->set_integrator(v1::INTEGRATOR_PATH);
  spec.mutable_plan()->mutable_skipping()->set_stride(stride);
  spec.mutable_plan()->mutable_skipping()->set_rounds(rounds);
  spec.mutable_plan()->mutable_skipping()->set_samples_per_pixel(2);
  spec.set_seed(11);
  return spec;
}

// Stores a new job the way SubmitJob does (its row first: tasks have no row until they change),
// then makes it visible to the scheduler; returns its id.
inline std::string SubmitStored(Scheduler& scheduler, SqliteStore& db, JobConfig config) {
  std::unique_ptr<Job> job = scheduler.PrepareJob(std::move(config));
  JobRow row{job->id(),
             job->seq(),
             job->config().spec.SerializeAsString(),
             JobState::kQueued,
             "",
             job->submitted_unix_ms(),
             0};
  db.InsertJob(row, {});
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  return id;
}

// The Cornell box shipped in scenes/ (small, with a manifest camera).
inline fs::path CornellManifest() {
  return fs::path(PF_SOURCE_DIR) / "scenes" / "cornell-box" / "cornell-box.json";
}

inline v1::SceneBundle ToProto(const SceneBundle& b) {
  v1::SceneBundle out;
  BundleToProto(b, &out);
  return out;
}

// An in-process coordinator on 127.0.0.1:0 and stubs on a real channel to it.
class LiveCoordinator {
 public:
  explicit LiveCoordinator(CoordinatorOptions options) {
    coordinator = std::make_unique<Coordinator>(options);
    port = coordinator->Start();
    channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
    render = v1::RenderService::NewStub(channel);
    worker = v1::WorkerService::NewStub(channel);
  }
  std::unique_ptr<Coordinator> coordinator;
  int port = 0;
  std::shared_ptr<grpc::Channel> channel;
  std::unique_ptr<v1::RenderService::Stub> render;
  std::unique_ptr<v1::WorkerService::Stub> worker;
};

// A client context with a deadline (every client call has one) and an optional bearer token.
inline std::unique_ptr<grpc::ClientContext> Ctx(const std::string& token = "", double seconds = 20) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000)));
  if (!token.empty()) ctx->AddMetadata("authorization", "Bearer " + token);
  return ctx;
}

// Uploads the shipped Cornell box through RenderService; returns its scene hash.
inline std::string UploadCornell(LiveCoordinator& live) {
  v1::UploadSceneRequest req;
  *req.mutable_bundle() = ToProto(CollectBundle(CornellManifest()));
  v1::UploadSceneResponse resp;
  const grpc::Status st = live.render->UploadScene(Ctx().get(), req, &resp);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return resp.scene_hash();
}

// LeaseTask as `worker` (waiting up to `wait` seconds for work): the task, or nullopt if none.
inline std::optional<v1::Task> TakeLease(LiveCoordinator& live, const std::string& worker = "w1",
                                         double wait = 0) {
  v1::LeaseTaskRequest req;
  req.set_worker_id(worker);
  req.set_worker_version(PF_VERSION);
  req.set_wait_seconds(wait);
  v1::LeaseTaskResponse resp;
  const grpc::Status st = live.worker->LeaseTask(Ctx("", wait + 10).get(), req, &resp);
  EXPECT_TRUE(st.ok()) << st.error_message();
  if (!resp.has_task()) return std::nullopt;
  return resp.task();
}

// One UploadPhotonChunk stream of `bytes` (one part, its checksums those of `bytes`) for `lease_id`
// from `worker_id`.
inline grpc::Status UploadPiece(LiveCoordinator& live, const std::string& lease_id,
                                const std::string& worker_id, const std::string& bytes, bool* accepted) {
  v1::UploadPhotonChunkResponse resp;
  auto ctx = Ctx();
  std::unique_ptr<grpc::ClientWriter<v1::PhotonChunkPart>> writer(
      live.worker->UploadPhotonChunk(ctx.get(), &resp));
  v1::PhotonChunkPart part;
  part.set_lease_id(lease_id);
  part.set_worker_id(worker_id);
  part.set_total_bytes(bytes.size());
  part.set_digest(Sha256Hex(bytes));
  part.set_offset(0);
  part.set_data(bytes);
  part.set_sha256(Sha256Hex(bytes));
  writer->Write(part);
  writer->WritesDone();
  const grpc::Status st = writer->Finish();
  *accepted = resp.accepted();
  return st;
}

// Options of a coordinator in `data_dir` for tests that count leases: no verification leases at random.
inline CoordinatorOptions CountingOptions(const fs::path& data_dir) {
  CoordinatorOptions o;
  o.verify_fraction = 0;
  o.data_dir = data_dir;
  return o;
}

// A fixture: an in-process coordinator with both role tokens set ("client-token", "worker-token").
class TokenCoordinatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    CoordinatorOptions o = CountingOptions(dir_.path() / "data");
    o.client_token = "client-token";
    o.worker_token = "worker-token";
    live_ = std::make_unique<LiveCoordinator>(o);
  }
  TempDir dir_;
  std::unique_ptr<LiveCoordinator> live_;
};

// A fixture: an in-process coordinator in a fresh data folder with the Cornell box uploaded.
class LiveCoordinatorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    live_ = std::make_unique<LiveCoordinator>(CountingOptions(dir_.path() / "data"));
    hash_ = UploadCornell(*live_);
    ASSERT_FALSE(HasFailure()) << "the scene upload failed";
  }

  TempDir dir_;
  std::unique_ptr<LiveCoordinator> live_;
  std::string hash_;
};

// The scheduler's CompletionProbe (server/scheduling/completion_probe.h) as a settable function:
// runs `hook` between a result's check and its commit. Set before the Complete it is meant for.
class HookProbe final : public CompletionProbe {
 public:
  void Set(std::function<void(const std::string& lease_id)> hook) { hook_ = std::move(hook); }
  void BeforeCommit(const std::string& lease_id) override {
    if (hook_) hook_(lease_id);
  }

 private:
  std::function<void(const std::string&)> hook_;
};

// A scheduler on a FakeClock (30 s leases, 3 attempts) with a HookProbe, and Submit: the fixture of
// the scheduler's rule and concurrency tests.
class SchedulerFixture : public ::testing::Test {
 protected:
  SchedulerFixture()
      : scheduler_(clock_, SchedulerOptions{.lease_seconds = 30, .max_attempts = 3, .probe = &probe_}) {}

  std::string Submit(const JobConfig& config) {
    std::unique_ptr<Job> job = scheduler_.PrepareJob(config);
    const std::string id = job->id();
    scheduler_.AddJob(std::move(job));
    return id;
  }

  FakeClock clock_;
  HookProbe probe_;  // before scheduler_, which holds it
  Scheduler scheduler_;
};

}  // namespace pf::server::testing
