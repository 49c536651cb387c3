// WorkerService through a real in-process gRPC server: result validation re-queues the task,
// duplicates are ignored, long polls wake up on new work, FetchScene returns the bundle that
// hashes to the task's scene hash; WatchJob/GetImage; and an end-to-end farm run with real
// rendering, a coordinator crash and restart, bit-identical to the single-process render.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <future>
#include <map>
#include <optional>
#include <set>
#include <thread>

#include "common/core/sha256.h"
#include "common/image/exr_io.h"
#include "common/photon/photon_chunk.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/plan/task_executor.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm_version.h"
#include "server/scheduling/distributed_maps.h"
#include "server/scheduling/scheduler.h"
#include "server/store/persister.h"
#include "server/store/scene_store.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using testing::Ctx;
using ::testing::HasSubstr;
using testing::LiveCoordinator;
using testing::TakeLease;
using testing::TempDir;
using testing::UploadPiece;
namespace v1 = photonfarm::v1;
namespace fs = std::filesystem;

std::string Upload(LiveCoordinator& live) {
  return testing::UploadCornell(live);
}

// One map, one sample per pixel, one tile: a job of a single task.
v1::Plan OneMapPlan() {
  v1::Plan plan;
  plan.mutable_multiple_maps()->set_maps(1);
  plan.mutable_multiple_maps()->set_samples_per_pixel(1);
  return plan;
}

// The manifest camera at a small resolution.
v1::JobSpec SmallSpec(const std::string& hash, v1::Plan plan, uint64_t seed = 5) {
  v1::JobSpec spec;
  spec.set_scene_hash(hash);
  spec.mutable_camera()->set_width(24);
  spec.mutable_camera()->set_height(18);
  spec.mutable_settings()->set_integrator(v1::INTEGRATOR_PHOTONMAP);
  spec.mutable_settings()->mutable_photon_map()->set_photons(3000);
  spec.mutable_settings()->mutable_photon_map()->set_k(20);
  *spec.mutable_plan() = std::move(plan);
  spec.set_seed(seed);
  return spec;
}

v1::Plan SkippingPlan(uint32_t stride, uint32_t rounds) {
  v1::Plan p;
  p.mutable_skipping()->set_stride(stride);
  p.mutable_skipping()->set_rounds(rounds);
  p.mutable_skipping()->set_samples_per_pixel(1);
  return p;
}

std::string SubmitOk(LiveCoordinator& live, const v1::JobSpec& spec) {
  v1::SubmitJobRequest req;
  *req.mutable_spec() = spec;
  v1::SubmitJobResponse resp;
  const grpc::Status st = live.render->SubmitJob(Ctx().get(), req, &resp);
  EXPECT_TRUE(st.ok()) << st.error_message();
  return resp.job_id();
}

v1::JobStatus GetJob(LiveCoordinator& live, const std::string& id) {
  v1::GetJobRequest req;
  req.set_job_id(id);
  v1::JobStatus s;
  EXPECT_TRUE(live.render->GetJob(Ctx().get(), req, &s).ok());
  return s;
}

grpc::Status Complete(LiveCoordinator& live, const v1::Task& task, const std::vector<float>& sums,
                      bool* merged = nullptr, const std::string& worker = "w1") {
  v1::CompleteTaskRequest req;
  req.set_lease_id(task.lease_id());
  req.set_worker_id(worker);
  req.mutable_rgb_sums()->Add(sums.begin(), sums.end());
  v1::CompleteTaskResponse resp;
  const grpc::Status st = live.worker->CompleteTask(Ctx().get(), req, &resp);
  if (merged) *merged = resp.merged();
  return st;
}

std::vector<float> SyntheticFor(const v1::Task& task) {
  return testing::SyntheticResult(TaskSpecFromProto(task), int(task.camera().width()),
                                  int(task.camera().height()));
}

std::string GetImageBytes(LiveCoordinator& live, const std::string& id) {
  v1::GetImageRequest req;
  req.set_job_id(id);
  auto ctx = Ctx();
  auto reader = live.render->GetImage(ctx.get(), req);
  std::string bytes;
  v1::ImageChunk chunk;
  uint32_t expected = 0;
  while (reader->Read(&chunk)) {
    EXPECT_EQ(chunk.index(), expected++);
    EXPECT_LE(chunk.exr_bytes().size(), size_t(1) << 20);
    bytes += chunk.exr_bytes();
  }
  EXPECT_TRUE(reader->Finish().ok());
  return bytes;
}

// A minimal in-test worker: fetches the scene once, renders tasks with the same ExecuteTask the
// real worker uses, delivers the results.
class TestWorker {
 public:
  TestWorker(LiveCoordinator* live, fs::path cache_dir) : live_(live), cache_dir_(std::move(cache_dir)) {}
  void Rebind(LiveCoordinator* live) { live_ = live; }

  // Renders up to `max_tasks` tasks; returns how many were merged.
  int Run(int max_tasks) {
    int merged_count = 0;
    for (int i = 0; i < max_tasks; ++i) {
      std::optional<v1::Task> task = TakeLease(*live_, "test-worker", 0.2);
      if (!task) break;
      const SceneRuntime& scene = Scene(task->scene_hash(), task->scene_entry());
      const TaskOutput out = ExecuteTask(
          scene, task->scene_hash(), CameraFromProto(task->camera(), "task.camera"),
          SettingsFromProto(task->settings(), "task.settings"), TaskSpecFromProto(*task), 1, &maps_);
      ++executed_[task->task_id()];
      bool merged = false;
      EXPECT_TRUE(Complete(*live_, *task, out.rgb_sums, &merged, "test-worker").ok());
      merged_count += merged;
    }
    return merged_count;
  }
  const std::map<uint64_t, int>& executed() const { return executed_; }

  const SceneRuntime& Scene(const std::string& hash, const std::string& entry) {
    auto it = scenes_.find(hash);
    if (it != scenes_.end()) return *it->second;
    v1::FetchSceneRequest req;
    req.set_scene_hash(hash);
    auto ctx = Ctx();
    auto reader = live_->worker->FetchScene(ctx.get(), req);
    SceneBundle bundle;
    bundle.entry = entry;
    v1::SceneFile f;
    while (reader->Read(&f)) {
      if (!bundle.files.empty() && bundle.files.back().first == f.path())
        bundle.files.back().second += f.content();
      else
        bundle.files.emplace_back(f.path(), f.content());
    }
    EXPECT_TRUE(reader->Finish().ok());
    EXPECT_EQ(BundleHash(bundle), hash) << "the fetched bundle is the uploaded one";
    const fs::path dir = cache_dir_ / hash;
    WriteBundle(bundle, dir);
    auto runtime = std::make_unique<SceneRuntime>(LoadBundle(dir, entry));
    return *scenes_.emplace(hash, std::move(runtime)).first->second;
  }

 private:
  LiveCoordinator* live_;
  fs::path cache_dir_;
  std::map<std::string, std::unique_ptr<SceneRuntime>> scenes_;
  PhotonMapCache maps_{4};
  std::map<uint64_t, int> executed_;
};

using WorkerServiceTest = testing::LiveCoordinatorTest;

TEST_F(WorkerServiceTest, BadResultsAreRejectedAndTheTaskIsRerun) {
  v1::Plan plan = OneMapPlan();
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, plan));
  std::optional<v1::Task> t1 = TakeLease(*live_);
  ASSERT_TRUE(t1.has_value());
  EXPECT_EQ(t1->attempt(), 1u);
  EXPECT_EQ(t1->scene_entry(), "cornell-box.json");
  bool merged = true;
  grpc::Status st = Complete(*live_, *t1, {1, 2, 3}, &merged);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(
      st.error_message(),
      "rgb_sums: result rejected, the task is re-queued: result: rgb_sums has 3 values, expected 1296 (3 per "
      "pixel of the subset)");
  EXPECT_FALSE(merged);

  std::optional<v1::Task> t2 = TakeLease(*live_);
  ASSERT_TRUE(t2.has_value());
  EXPECT_EQ(t2->task_id(), t1->task_id());
  EXPECT_EQ(t2->attempt(), 2u);
  std::vector<float> nan_sums = SyntheticFor(*t2);
  nan_sums[100] = std::numeric_limits<float>::infinity();
  st = Complete(*live_, *t2, nan_sums);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(st.error_message(), HasSubstr("rgb_sums[100] is not finite"));

  std::optional<v1::Task> t3 = TakeLease(*live_);
  ASSERT_TRUE(t3.has_value());
  EXPECT_EQ(t3->attempt(), 3u);
  EXPECT_TRUE(Complete(*live_, *t3, SyntheticFor(*t3), &merged).ok());
  EXPECT_TRUE(merged);
  EXPECT_TRUE(Complete(*live_, *t3, SyntheticFor(*t3), &merged).ok());
  EXPECT_FALSE(merged) << "duplicate";
  EXPECT_TRUE(Complete(*live_, *t1, SyntheticFor(*t1), &merged).ok());
  EXPECT_FALSE(merged) << "late, from a dead attempt";
  const v1::JobStatus s = GetJob(*live_, id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), 1u);
  EXPECT_EQ(s.samples_merged(), 24u * 18u);
}

// A worker's failure reason is logged and shown by `pf`; control characters in it
// would forge log lines or drive the user's terminal.
TEST_F(WorkerServiceTest, FailureReasonsAreSanitized) {
  v1::Plan plan = OneMapPlan();
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, plan));
  std::optional<v1::Task> t = TakeLease(*live_);
  ASSERT_TRUE(t.has_value());
  v1::FailTaskRequest fail;
  fail.set_lease_id(t->lease_id());
  fail.set_worker_id("w1");
  fail.set_reason("disk full\n[error] forged line \x1b[2J");
  fail.set_retryable(false);
  v1::FailTaskResponse failed;
  ASSERT_TRUE(live_->worker->FailTask(Ctx().get(), fail, &failed).ok());
  const v1::JobStatus s = GetJob(*live_, id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_FAILED);
  EXPECT_THAT(s.failure_reason(), HasSubstr("disk full\\x0a[error] forged line \\x1b[2J"));
  EXPECT_EQ(s.failure_reason().find('\n'), std::string::npos);
  EXPECT_EQ(s.failure_reason().find('\x1b'), std::string::npos);
}

// FailTask(retryable = false) ends the whole job, so only the worker holding the lease
// may send it. A stranger with the lease id is PERMISSION_DENIED, an unknown lease NOT_FOUND, a
// missing worker_id INVALID_ARGUMENT; none of them changes the job, and the holder still merges.
TEST_F(WorkerServiceTest, OnlyTheLeaseHolderCanFailItsTask) {
  v1::Plan plan = OneMapPlan();
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, plan));
  std::optional<v1::Task> t = TakeLease(*live_, "holder", 0);
  ASSERT_TRUE(t.has_value());
  auto fail = [&](const std::string& lease_id, const std::string& worker_id) {
    v1::FailTaskRequest req;
    req.set_lease_id(lease_id);
    req.set_worker_id(worker_id);
    req.set_reason("sabotage");
    req.set_retryable(false);
    v1::FailTaskResponse resp;
    return live_->worker->FailTask(Ctx().get(), req, &resp);
  };
  grpc::Status st = fail(t->lease_id(), "stranger");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("held by another worker; nothing was changed"));
  EXPECT_THAT(st.error_message(), ::testing::Not(HasSubstr("holder"))) << "the holder is not revealed";
  st = fail(t->lease_id(), "");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("worker_id: required"));
  st = fail(t->job_id() + ".0.1.0123456789abcdef0123456789abcdef", "holder");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << st.error_message();
  v1::JobStatus s = GetJob(*live_, id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING) << s.failure_reason();
  EXPECT_EQ(s.failure_reason(), "");
  bool merged = false;
  EXPECT_TRUE(Complete(*live_, *t, SyntheticFor(*t), &merged, "holder").ok());
  EXPECT_TRUE(merged) << "the holder's lease survived the stranger's FailTask";
  EXPECT_EQ(GetJob(*live_, id).state(), v1::JOB_STATE_SUCCEEDED);
}

// Leases are bound to their worker (docs/security.md): ExtendLease and CompleteTask name the
// caller (worker_id, required: INVALID_ARGUMENT naming it); another worker's heartbeat or result is
// PERMISSION_DENIED and changes nothing, and the holder's result still merges.
TEST_F(WorkerServiceTest, OnlyTheLeaseHolderCanExtendOrCompleteItsTask) {
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, OneMapPlan()));
  std::optional<v1::Task> t = TakeLease(*live_, "holder", 0);
  ASSERT_TRUE(t.has_value());
  auto extend = [&](const std::string& worker_id) {
    v1::ExtendLeaseRequest req;
    req.set_lease_id(t->lease_id());
    req.set_worker_id(worker_id);
    req.set_progress(0.5);
    v1::ExtendLeaseResponse resp;
    const grpc::Status st = live_->worker->ExtendLease(Ctx().get(), req, &resp);
    return std::make_pair(st, resp.ok());
  };
  auto [st, ok] = extend("stranger");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("held by another worker; nothing was changed"));
  std::tie(st, ok) = extend("");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message(), "worker_id: required");
  std::tie(st, ok) = extend("holder");
  EXPECT_TRUE(st.ok() && ok) << st.error_message();

  bool merged = true;
  st = Complete(*live_, *t, SyntheticFor(*t), &merged, "stranger");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
  EXPECT_FALSE(merged);
  st = Complete(*live_, *t, SyntheticFor(*t), &merged, "");
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message(), "worker_id: required");
  EXPECT_EQ(GetJob(*live_, id).tasks_done(), 0u);
  EXPECT_TRUE(Complete(*live_, *t, SyntheticFor(*t), &merged, "holder").ok());
  EXPECT_TRUE(merged) << "the holder's lease survived the stranger's calls";
  EXPECT_EQ(GetJob(*live_, id).state(), v1::JOB_STATE_SUCCEEDED);
}

// The hostile farm: a second worker renewed another's piece lease, uploaded an empty piece (it was
// taken), the honest upload was refused, and the job SUCCEEDED with a third of its photons. Now
// the lease is bound to its holder: the stranger's heartbeat, upload and FailTask are refused,
// change nothing and convict the stranger (blocklisted for the job); the holder's own empty piece is refused
// too (its first photons are not the trace of them), and convicts it (docs/farm.md "Result verification":
// blocklisted for the job, the piece queued again); the honest piece, from another worker, is taken and the
// map built from it is complete.
TEST_F(WorkerServiceTest, PieceLeaseHijackIsRefusedAndTheHonestPieceCompletesTheMap) {
  v1::JobSpec spec = SmallSpec(hash_, OneMapPlan());
  spec.mutable_settings()->mutable_photon_map()->set_photons(8192);
  spec.mutable_settings()->mutable_photon_map()->set_map_tracing(v1::MAP_TRACING_DISTRIBUTED);
  const std::string id = SubmitOk(*live_, spec);
  const std::optional<v1::Task> piece = TakeLease(*live_, "holder", 5);
  ASSERT_TRUE(piece.has_value() && piece->has_trace_chunk()) << "pieces are leased first";
  // One form for every lease (lease_table.h): job, piece, attempt, 128 bits from the CSPRNG.
  EXPECT_THAT(piece->lease_id(), ::testing::MatchesRegex(id + "\\.0\\.1\\.[0-9a-f]{32}"))
      << "from the CSPRNG";
  const std::string lease = piece->lease_id();

  // What the honest worker traces (as Worker::RunMapPiece, worker/worker.cpp, does).
  const SceneRuntime scene(LoadBundle(live_->coordinator->scenes().DirectoryOf(hash_), piece->scene_entry()));
  PhotonMapsOptions mo =
      SettingsFromProto(piece->settings(), "settings").Resolved(scene.description).MapsOptions();
  mo.tracing.map_seed = piece->map_seed();
  const PhotonChunk traced = TracePhotonChunk(
      scene.accel, scene.lights, mo, piece->trace_chunk().photon_begin(), piece->trace_chunk().photon_end());
  PhotonChunk empty = traced;  // the right range and attributes, no photons
  for (PhotonChunk::List& l : empty.lists) l = PhotonChunk::List{};
  empty.stored_power = {0, 0, 0};

  // The stranger.
  v1::ExtendLeaseRequest ext;
  ext.set_lease_id(lease);
  ext.set_worker_id("thief");
  v1::ExtendLeaseResponse ext_resp;
  grpc::Status st = live_->worker->ExtendLease(Ctx().get(), ext, &ext_resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
  bool accepted = true;
  st = UploadPiece(*live_, lease, "thief", SerializePhotonChunk(empty), &accepted);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
  EXPECT_FALSE(accepted);
  st = UploadPiece(*live_, lease, "", SerializePhotonChunk(empty), &accepted);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_EQ(st.error_message(), "worker_id: required");
  v1::FailTaskRequest fail;
  fail.set_lease_id(lease);
  fail.set_worker_id("thief");
  fail.set_reason("sabotage");
  v1::FailTaskResponse fail_resp;
  st = live_->worker->FailTask(Ctx().get(), fail, &fail_resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
  EXPECT_EQ(live_->coordinator->maps().counters().chunks_stored, 0u);

  // The holder's empty piece is no piece either: refused, and the holder convicted.
  st = UploadPiece(*live_, lease, "holder", SerializePhotonChunk(empty), &accepted);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("not the coordinator's trace of them"));
  EXPECT_EQ(live_->coordinator->maps().counters().chunks_stored, 0u);
  const v1::JobStatus convicted = GetJob(*live_, id);
  ASSERT_EQ(convicted.blocklisted_workers_size(), 2) << "the thief, for presenting another's lease";
  std::set<std::string> blocklisted;
  for (const auto& b : convicted.blocklisted_workers()) blocklisted.insert(b.worker_id());
  EXPECT_EQ(blocklisted, (std::set<std::string>{"holder", "thief"}));
  EXPECT_FALSE(TakeLease(*live_, "holder", 0).has_value()) << "blocklisted for the job";

  // The honest piece, from another worker: taken, and the map is built from all of its photons.
  const std::optional<v1::Task> again = TakeLease(*live_, "honest", 5);
  ASSERT_TRUE(again.has_value() && again->has_trace_chunk());
  EXPECT_EQ(again->trace_chunk().chunk_index(), piece->trace_chunk().chunk_index());
  st = UploadPiece(*live_, again->lease_id(), "honest", SerializePhotonChunk(traced), &accepted);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_TRUE(accepted);
  const std::optional<v1::Task> render = TakeLease(*live_, "honest", 20);
  ASSERT_TRUE(render.has_value() && render->has_map()) << "the map is built and its render task released";
  const std::optional<fs::path> file = live_->coordinator->maps().MapFile(render->map().map_key());
  ASSERT_TRUE(file.has_value());
  std::ifstream in(*file, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const PhotonMaps built = DeserializePhotonMaps(bytes);
  const PhotonMaps whole = AssemblePhotonMaps(std::vector<PhotonChunk>{traced}, mo);
  EXPECT_EQ(built.global->size(), whole.global->size());
  EXPECT_GT(built.global->size(), 0u);
  EXPECT_EQ(built.caustic ? built.caustic->size() : 0, whole.caustic ? whole.caustic->size() : 0);
  EXPECT_EQ(built.direct ? built.direct->size() : 0, whole.direct ? whole.direct->size() : 0);
  bool merged = false;
  EXPECT_TRUE(Complete(*live_, *render, SyntheticFor(*render), &merged, "honest").ok());
  EXPECT_TRUE(merged);
  EXPECT_EQ(GetJob(*live_, id).state(), v1::JOB_STATE_SUCCEEDED);
}

TEST_F(WorkerServiceTest, LeaseRequestsAreValidated) {
  v1::LeaseTaskRequest req;
  v1::LeaseTaskResponse resp;
  grpc::Status st = live_->worker->LeaseTask(Ctx().get(), req, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message(), "worker_id: required");
  req.set_worker_id("w");
  req.set_worker_version(PF_VERSION);
  req.set_wait_seconds(-1);
  st = live_->worker->LeaseTask(Ctx().get(), req, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(st.error_message(), HasSubstr("wait_seconds"));
  v1::ExtendLeaseRequest ext;
  v1::ExtendLeaseResponse ext_resp;
  EXPECT_EQ(live_->worker->ExtendLease(Ctx().get(), ext, &ext_resp).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  ext.set_lease_id("job-1.0.1.deadbeef");
  st = live_->worker->ExtendLease(Ctx().get(), ext, &ext_resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message(), "worker_id: required") << "a lease is bound to its worker";
  ext.set_worker_id("w");
  ASSERT_TRUE(live_->worker->ExtendLease(Ctx().get(), ext, &ext_resp).ok());
  EXPECT_FALSE(ext_resp.ok()) << "unknown lease: stop";
}

// Farms run one build (docs/farm.md, "Upgrades"): a worker of another build, or one too old to
// say which, gets FAILED_PRECONDITION naming both builds and is listed as refused (with the build
// it named); a worker of the coordinator's build gets its (empty) answer and is listed with its
// build, no longer refused.
TEST_F(WorkerServiceTest, LeasesGoOnlyToWorkersOfTheCoordinatorsBuild) {
  const auto listed = [&](const std::string& id) -> std::optional<v1::WorkerInfo> {
    v1::ListWorkersResponse workers;
    EXPECT_TRUE(live_->render->ListWorkers(Ctx().get(), v1::ListWorkersRequest(), &workers).ok());
    for (const v1::WorkerInfo& w : workers.workers())
      if (w.worker_id() == id) return w;
    return std::nullopt;
  };
  v1::LeaseTaskRequest req;
  req.set_worker_id("old-worker");
  req.set_wait_seconds(0);
  v1::LeaseTaskResponse resp;
  req.set_worker_version("0.0.1-elsewhere");
  grpc::Status st = live_->worker->LeaseTask(Ctx().get(), req, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("'0.0.1-elsewhere'"));
  EXPECT_THAT(st.error_message(), HasSubstr(std::string("'") + PF_VERSION + "'"));
  EXPECT_THAT(st.error_message(), HasSubstr("--allow-mixed-versions"));
  std::optional<v1::WorkerInfo> w = listed("old-worker");
  ASSERT_TRUE(w);
  EXPECT_TRUE(w->refused());
  EXPECT_EQ(w->version(), "0.0.1-elsewhere");
  req.clear_worker_version();  // a worker older than the field
  st = live_->worker->LeaseTask(Ctx().get(), req, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::FAILED_PRECONDITION) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("build is none"));
  req.set_worker_version(std::string(PF_VERSION) + "\n");  // listed and logged: printable only
  st = live_->worker->LeaseTask(Ctx().get(), req, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("worker_version"));
  w = listed("old-worker");
  ASSERT_TRUE(w);
  EXPECT_TRUE(w->refused());
  EXPECT_EQ(w->version(), "") << "the last refusal's build (none); the malformed one is not recorded";

  req.set_worker_version(PF_VERSION);
  st = live_->worker->LeaseTask(Ctx().get(), req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_FALSE(resp.has_task()) << "no job was submitted";
  w = listed("old-worker");
  ASSERT_TRUE(w);
  EXPECT_FALSE(w->refused());
  EXPECT_EQ(w->version(), PF_VERSION);
}

// --allow-mixed-versions: the operator's choice to lease to other builds too (listed with theirs).
TEST(WorkerServiceMixedVersions, AllowMixedVersionsLeasesToOtherBuilds) {
  TempDir dir;
  CoordinatorOptions o;
  o.verify_fraction = 0;  // no verification leases at random: these tests count leases
  o.data_dir = dir.path() / "data";
  o.allow_mixed_versions = true;
  LiveCoordinator live(o);
  v1::LeaseTaskRequest req;
  req.set_worker_id("other-build");
  req.set_worker_version("0.0.1-elsewhere");
  req.set_wait_seconds(0);
  v1::LeaseTaskResponse resp;
  const grpc::Status st = live.worker->LeaseTask(Ctx().get(), req, &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  v1::ListWorkersResponse workers;
  ASSERT_TRUE(live.render->ListWorkers(Ctx().get(), v1::ListWorkersRequest(), &workers).ok());
  ASSERT_EQ(workers.workers_size(), 1);
  EXPECT_EQ(workers.workers(0).version(), "0.0.1-elsewhere");
}

TEST_F(WorkerServiceTest, LongPollWaitsWithoutSpinningAndWakesOnNewWork) {
  // Nothing queued: an empty answer after the wait.
  auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(TakeLease(*live_, "w1", 0.3).has_value());
  double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(waited, 0.25);
  EXPECT_LT(waited, 3.0);

  // The poll is parked: it waits as a waiter of the scheduler, and nothing searches the queue on
  // its behalf while it waits (a poll that retried in a loop would pass the timing checks alone).
  start = std::chrono::steady_clock::now();
  auto poll = std::async(std::launch::async, [&] { return TakeLease(*live_, "parked", 20); });
  Scheduler& scheduler = live_->coordinator->scheduler();
  for (int i = 0; i < 500 && scheduler.counters().parked_polls == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  ASSERT_EQ(scheduler.counters().parked_polls, 1u) << "the poll never parked";
  const uint64_t attempts = scheduler.counters().lease_attempts;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_EQ(scheduler.counters().lease_attempts, attempts) << "the parked poll kept searching the queue";
  EXPECT_EQ(scheduler.counters().parked_polls, 1u);
  // It returns as soon as a job is submitted, long before its 20 s wait.
  v1::Plan plan = OneMapPlan();
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, plan));
  std::optional<v1::Task> task = poll.get();
  waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ASSERT_TRUE(task.has_value());
  EXPECT_EQ(task->job_id(), id);
  EXPECT_LT(waited, 5.0);
  EXPECT_EQ(GetJob(*live_, id).tasks_running(), 1u);
  EXPECT_EQ(scheduler.counters().parked_polls, 0u) << "a served poll leaves the waiters";

  // A poll whose client gives up is released (no lease leaks to a dead caller).
  {
    v1::LeaseTaskRequest req;
    req.set_worker_id("impatient");
    req.set_worker_version(PF_VERSION);
    req.set_wait_seconds(20);
    v1::LeaseTaskResponse resp;
    const grpc::Status st = live_->worker->LeaseTask(Ctx("", 0.3).get(), req, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED);
  }
}

TEST_F(WorkerServiceTest, FetchSceneStreamsTheBundleOfTheTask) {
  v1::Plan plan = OneMapPlan();
  SubmitOk(*live_, SmallSpec(hash_, plan));
  std::optional<v1::Task> task = TakeLease(*live_);
  ASSERT_TRUE(task.has_value());
  EXPECT_EQ(task->scene_hash(), hash_);
  TestWorker worker(live_.get(), dir_.path() / "worker-cache");
  const SceneRuntime& scene = worker.Scene(task->scene_hash(), task->scene_entry());  // checks the hash
  EXPECT_GT(scene.description.NumTriangles(), 0u);

  // A bundle larger than gRPC's default 4 MiB message, with a file that streams in several chunks.
  SceneBundle big = CollectBundle(testing::CornellManifest());
  std::string blob(5 << 20, '\0');
  for (size_t i = 0; i < blob.size(); ++i) blob[i] = char((i * 2654435761u) >> 13);
  big.files.emplace_back("textures/big.bin", blob);
  v1::UploadSceneRequest up;
  *up.mutable_bundle() = testing::ToProto(big);
  v1::UploadSceneResponse up_resp;
  const grpc::Status up_st = live_->render->UploadScene(Ctx().get(), up, &up_resp);
  ASSERT_TRUE(up_st.ok()) << up_st.error_message();
  EXPECT_EQ(up_resp.scene_hash(), BundleHash(big));
  {
    v1::FetchSceneRequest req;
    req.set_scene_hash(up_resp.scene_hash());
    auto ctx = Ctx();
    auto reader = live_->worker->FetchScene(ctx.get(), req);
    SceneBundle fetched;
    fetched.entry = big.entry;
    v1::SceneFile f;
    int messages = 0;
    while (reader->Read(&f)) {
      ++messages;
      EXPECT_LE(f.content().size(), size_t(1) << 20);
      if (!fetched.files.empty() && fetched.files.back().first == f.path())
        fetched.files.back().second += f.content();
      else
        fetched.files.emplace_back(f.path(), f.content());
    }
    ASSERT_TRUE(reader->Finish().ok());
    EXPECT_GE(messages, int(big.files.size()) + 4);
    EXPECT_EQ(BundleHash(fetched), up_resp.scene_hash());
  }

  v1::FetchSceneRequest req;
  req.set_scene_hash(std::string(64, 'e'));
  auto ctx = Ctx();
  auto reader = live_->worker->FetchScene(ctx.get(), req);
  v1::SceneFile f;
  EXPECT_FALSE(reader->Read(&f));
  const grpc::Status st = reader->Finish();
  EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(st.error_message(), HasSubstr("scene_hash: unknown scene"));
}

// Resident memory of this process in MiB (VmRSS).
long OwnRssMiB() {
  std::ifstream in("/proc/self/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6)) / 1024;
  return -1;
}

// FetchScene streams from the stored files one chunk at a time (server/rpc/buffered_stream.h):
// twenty streams of a 32 MiB bundle that nobody reads hold a few chunks each (server message,
// serialisation, client receive window: ~115 MiB measured for both ends, this process being the
// client too), not a copy of the bundle each (+691 MiB before). Every stream then
// still delivers the whole bundle.
TEST_F(WorkerServiceTest, UnreadFetchSceneStreamsHoldChunksNotBundles) {
  SceneBundle big = CollectBundle(testing::CornellManifest());
  std::string blob(32 << 20, '\0');
  for (size_t i = 0; i < blob.size(); ++i) blob[i] = char((i * 2654435761u) >> 13);
  big.files.emplace_back("textures/big.bin", std::move(blob));
  std::string hash;
  {
    v1::UploadSceneRequest up;
    *up.mutable_bundle() = testing::ToProto(big);
    v1::UploadSceneResponse resp;
    const grpc::Status st = live_->render->UploadScene(Ctx().get(), up, &resp);
    ASSERT_TRUE(st.ok()) << st.error_message();
    hash = resp.scene_hash();
  }
  big.files.clear();
  const long before = OwnRssMiB();
  constexpr int kStreams = 20;
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<v1::SceneFile>>> readers;
  v1::FetchSceneRequest req;
  req.set_scene_hash(hash);
  v1::SceneFile f;
  std::vector<uint64_t> bytes;
  for (int i = 0; i < kStreams; ++i) {
    contexts.push_back(Ctx("", 60));
    readers.push_back(live_->worker->FetchScene(contexts.back().get(), req));
    ASSERT_TRUE(readers.back()->Read(&f));  // the stream is open and producing
    bytes.push_back(f.content().size());
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // let the server run ahead if it would
  const long during = OwnRssMiB();
  RecordProperty("rss_growth_mib", int(during - before));
  EXPECT_LT(during - before, 250) << "RSS " << before << " -> " << during << " MiB with " << kStreams
                                  << " unread streams of a 32 MiB bundle";
  for (int i = 0; i < kStreams; ++i) {
    while (readers[i]->Read(&f)) bytes[i] += f.content().size();
    EXPECT_TRUE(readers[i]->Finish().ok());
    EXPECT_GT(bytes[i], uint64_t(32) << 20);
  }
}

TEST_F(WorkerServiceTest, WatchJobDeliversSnapshotsWithFallingNoiseAndEndsWithTheFinalImage) {
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, SkippingPlan(2, 6)));
  std::vector<v1::JobUpdate> updates;
  std::thread watcher([&] {
    v1::WatchJobRequest req;
    req.set_job_id(id);
    req.set_include_images(true);
    req.set_min_interval_seconds(0.001);
    auto ctx = Ctx("", 60);
    auto reader = live_->render->WatchJob(ctx.get(), req);
    v1::JobUpdate u;
    while (reader->Read(&u)) updates.push_back(u);
    const grpc::Status st = reader->Finish();
    EXPECT_TRUE(st.ok()) << st.error_message();
  });
  // A slow synthetic worker, so that the watcher sees the job progress.
  for (;;) {
    std::optional<v1::Task> task = TakeLease(*live_);
    if (!task) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
    bool merged = false;
    ASSERT_TRUE(Complete(*live_, *task, SyntheticFor(*task), &merged).ok());
    EXPECT_TRUE(merged);
  }
  watcher.join();
  ASSERT_GE(updates.size(), 3u);
  EXPECT_EQ(updates.back().status().state(), v1::JOB_STATE_SUCCEEDED);
  // Snapshots (image chunk 0) whose noise estimate is known, in order: the noise falls.
  std::vector<double> noise;
  for (const v1::JobUpdate& u : updates) {
    ASSERT_TRUE(u.has_image());
    EXPECT_EQ(u.image().count(), 1u) << "a 24x18 EXR fits one chunk";
    if (u.status().estimated_noise_rms() >= 0) noise.push_back(u.status().estimated_noise_rms());
  }
  ASSERT_GE(noise.size(), 2u);
  EXPECT_LT(noise.back(), noise.front());
  // The last snapshot is the final image, byte for byte.
  EXPECT_EQ(updates.back().image().exr_bytes(), GetImageBytes(*live_, id));
  ImageMetadata meta;
  const Image img = DecodeExrFromMemory(updates.back().image().exr_bytes(), &meta);
  EXPECT_EQ(img.width(), 24);
  EXPECT_EQ(meta.at("job_id"), id);
  EXPECT_EQ(meta.at("spp"), "6");
  EXPECT_NE(meta.at("noise_rms"), "unknown");
}

TEST_F(WorkerServiceTest, WatchWithoutImagesEndsAfterCancel) {
  const std::string id = SubmitOk(*live_, SmallSpec(hash_, SkippingPlan(2, 2)));
  v1::WatchJobRequest req;
  req.set_job_id(id);
  req.set_min_interval_seconds(0.01);
  auto ctx = Ctx("", 30);
  auto reader = live_->render->WatchJob(ctx.get(), req);
  v1::JobUpdate u;
  ASSERT_TRUE(reader->Read(&u));
  EXPECT_EQ(u.status().state(), v1::JOB_STATE_QUEUED);
  EXPECT_FALSE(u.has_image());
  v1::CancelJobRequest cancel;
  cancel.set_job_id(id);
  v1::CancelJobResponse cr;
  ASSERT_TRUE(live_->render->CancelJob(Ctx().get(), cancel, &cr).ok());
  EXPECT_EQ(cr.status().state(), v1::JOB_STATE_CANCELLED);
  v1::JobUpdate last = u;
  while (reader->Read(&u)) last = u;
  EXPECT_TRUE(reader->Finish().ok());
  EXPECT_EQ(last.status().state(), v1::JOB_STATE_CANCELLED);
}

// The farm's promise in one process: real rendering through the coordinator, a coordinator crash
// in the middle, a restart on the same data directory — finished tasks are not re-run and the
// final image is bit-identical to the single-process render of the same plan and seed.
TEST(FarmEndToEnd, CrashAndRestartGiveTheSingleProcessImage) {
  TempDir dir;
  CoordinatorOptions o;
  o.verify_fraction = 0;  // no verification leases at random: these tests count leases
  o.data_dir = dir.path() / "data";
  auto live = std::make_unique<LiveCoordinator>(o);
  const std::string hash = Upload(*live);
  const v1::JobSpec spec = SmallSpec(hash, SkippingPlan(2, 3), /*seed=*/17);
  const std::string id = SubmitOk(*live, spec);
  TestWorker worker(live.get(), dir.path() / "worker");
  EXPECT_EQ(worker.Run(5), 5);
  EXPECT_EQ(GetJob(*live, id).tasks_done(), 5u);

  live->coordinator->SimulateCrash();
  live.reset();
  live = std::make_unique<LiveCoordinator>(o);
  EXPECT_EQ(live->coordinator->recovery().tasks_merged, 5u) << "acknowledged merges survive the crash";
  EXPECT_EQ(live->coordinator->recovery().tasks_requeued, 7u);
  worker.Rebind(live.get());
  EXPECT_EQ(worker.Run(100), 7);
  const v1::JobStatus s = GetJob(*live, id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), 12u);
  // Every task ran exactly once, across the crash.
  EXPECT_EQ(worker.executed().size(), 12u);
  for (const auto& [task, runs] : worker.executed()) EXPECT_EQ(runs, 1) << "task " << task;

  const Image farm = DecodeExrFromMemory(GetImageBytes(*live, id));
  const SceneRuntime& scene = worker.Scene(hash, "cornell-box.json");
  const Image local = RenderPlanLocally(scene, CameraFromProto(s.spec().camera(), "camera"),
                                        SettingsFromProto(s.spec().settings(), "settings"),
                                        PlanFromProto(s.spec().plan(), "plan"), 17, /*threads=*/2);
  ASSERT_EQ(farm.width(), local.width());
  ASSERT_EQ(farm.height(), local.height());
  size_t nonzero = 0;
  for (size_t p = 0; p < local.size(); ++p)
    for (int c = 0; c < 3; ++c) {
      ASSERT_EQ(farm[p][c], local[p][c]) << "pixel " << p << " channel " << c;
      nonzero += local[p][c] > 0;
    }
  EXPECT_GT(nonzero, local.size()) << "the image is not black";
}

}  // namespace
}  // namespace pf::server
