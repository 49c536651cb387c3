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
#include <string>
#include <vector>

#include "common/core/rng.h"
#include "common/plan/task_plan.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "proto/convert.h"
#include "server/coordinator.h"
#include "server/jobs/job_spec.h"

namespace pf::server::testing {

namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// A fresh directory per test, removed afterwards.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("pf_server_test_" + std::to_string(::getpid()) + "_" + (info ? std::string(info->name()) : "x") +
             "_" + std::to_string(counter++));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
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
  PlanSpec p;
  p.kind = PlanKind::kSkipping;
  p.stride = stride;
  p.rounds = rounds;
  p.samples_per_pixel = spp;
  return p;
}

inline PlanSpec MultipleMaps(uint32_t maps, uint32_t tile, uint32_t spp = 1) {
  PlanSpec p;
  p.kind = PlanKind::kMultipleMaps;
  p.maps = maps;
  p.tile_size = tile;
  p.samples_per_pixel = spp;
  return p;
}

// The Cornell box shipped in scenes/ (small, with a manifest camera).
inline fs::path CornellManifest() {
  return fs::path(PF_SOURCE_DIR) / "scenes" / "cornell-box" / "cornell-box.json";
}

inline v1::SceneBundle ToProto(const SceneBundle& b) {
  v1::SceneBundle out;
  out.set_entry(b.entry);
  for (const auto& [path, content] : b.files) {
    v1::SceneFile* f = out.add_files();
    f->set_path(path);
    f->set_content(content);
  }
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

}  // namespace pf::server::testing
