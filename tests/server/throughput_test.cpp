// Measurements, not checks (DISABLED_: run with --gtest_also_run_disabled_tests
// --gtest_filter='*Throughput*'): task completions per second through the real gRPC services
// with "instant" workers (synthetic results, no rendering), in both checkpoint modes, and bytes
// on the wire per task against the pixels of its subset.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>

#include <spdlog/spdlog.h>

#include "server/scheduling/scheduler.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using testing::Ctx;
using testing::LiveCoordinator;
using testing::TempDir;
namespace v1 = photonfarm::v1;

void Measure(double checkpoint_seconds, int clients) {
  spdlog::set_level(spdlog::level::warn);  // one log line per lease and merge would be measured too
  TempDir dir;
  CoordinatorOptions o;
  o.data_dir = dir.path() / "data";
  o.checkpoint_interval_seconds = checkpoint_seconds;
  o.executor_threads = 2;
  LiveCoordinator live(o);
  v1::UploadSceneRequest up;
  *up.mutable_bundle() = testing::ToProto(CollectBundle(testing::CornellManifest()));
  v1::UploadSceneResponse up_resp;
  ASSERT_TRUE(live.render->UploadScene(Ctx().get(), up, &up_resp).ok());
  v1::SubmitJobRequest submit;
  v1::JobSpec* spec = submit.mutable_spec();
  spec->set_scene_hash(up_resp.scene_hash());
  spec->mutable_camera()->set_width(256);
  spec->mutable_camera()->set_height(256);
  spec->mutable_settings()->set_integrator(v1::INTEGRATOR_PATH);
  spec->mutable_plan()->mutable_multiple_maps()->set_maps(20);
  spec->mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
  spec->mutable_plan()->mutable_multiple_maps()->set_tile_size(16);  // 256 tiles × 20 maps = 5120 tasks
  v1::SubmitJobResponse submitted;
  ASSERT_TRUE(live.render->SubmitJob(Ctx().get(), submit, &submitted).ok());

  std::atomic<uint64_t> completed{0}, wire_bytes{0}, pixels{0};
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int c = 0; c < clients; ++c)
    threads.emplace_back([&, c] {
      for (;;) {
        v1::LeaseTaskRequest lr;
        lr.set_worker_id("bench-" + std::to_string(c));
        lr.set_wait_seconds(0.2);
        v1::LeaseTaskResponse lease;
        if (!live.worker->LeaseTask(Ctx().get(), lr, &lease).ok() || !lease.has_task()) return;
        const v1::Task& t = lease.task();
        const std::vector<float> sums = testing::SyntheticResult(TaskSpecFromProto(t), 256, 256);
        v1::CompleteTaskRequest cr;
        cr.set_lease_id(t.lease_id());
        cr.mutable_rgb_sums()->Add(sums.begin(), sums.end());
        v1::CompleteTaskResponse resp;
        if (!live.worker->CompleteTask(Ctx().get(), cr, &resp).ok()) return;
        completed += resp.merged();
        wire_bytes += cr.ByteSizeLong() + lease.ByteSizeLong();
        pixels += sums.size() / 3;
      }
    });
  for (auto& t : threads) t.join();
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("checkpoint %s, %d clients: %llu tasks in %.2f s = %.0f completions/s; %.1f bytes on the wire per "
              "task (lease + result) for %.0f pixels = %.2f bytes/pixel\n",
              checkpoint_seconds > 0 ? "every 200 ms, acks at once" : "durable acks (journal)", clients,
              static_cast<unsigned long long>(completed.load()), seconds, completed / seconds,
              double(wire_bytes) / double(completed), double(pixels) / double(completed),
              double(wire_bytes) / double(pixels));
  v1::GetJobRequest get;
  get.set_job_id(submitted.job_id());
  v1::JobStatus status;
  ASSERT_TRUE(live.render->GetJob(Ctx().get(), get, &status).ok());
  EXPECT_EQ(status.state(), v1::JOB_STATE_SUCCEEDED);
  spdlog::set_level(spdlog::level::info);
}

TEST(Throughput, DISABLED_InstantWorkersIntervalCheckpoints) { Measure(0.2, 8); }
TEST(Throughput, DISABLED_InstantWorkersDurableAcks) { Measure(0, 8); }

}  // namespace
}  // namespace pf::server
