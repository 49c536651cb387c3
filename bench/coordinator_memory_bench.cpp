// coordinator_memory_bench: what one job of the largest allowed size (2^20 tasks,
// limits::kMaxTasksPerJob) costs the REAL coordinator (a pf-coordinator process on 127.0.0.1:0)
// in memory and on disk, through its life (docs/farm.md "Coordinator memory"):
//
//   started      the coordinator with the Cornell box uploaded
//   submitted    the job accepted (SubmitJob answered; its rows are durable)
//   cancelled    CancelJob answered and the persister's flush done (the database stops growing)
//   restarted    a new coordinator process on the same data folder, after ListJobs
//
// For each: VmRSS and VmHWM of the coordinator (/proc/PID/status) and the size of the database
// (coordinator.db plus its -wal file), and the time SubmitJob took. The job is 65536 maps of
// 16 one-pixel tiles (16×1 image, 1 spp, path tracer): its task list is everything it costs.
// --coordinator runs another build (e.g. one from before a change) for a before/after table.
//
//   build/bench/coordinator_memory_bench [--coordinator PATH] [--json-out FILE]

#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "bench/bench_stats.h"
#include "bench/coordinator_process.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "proto/convert.h"
#include "tests/util/job_specs.h"

namespace pf::bench {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

struct Options {
  std::string coordinator = std::string(PF_BUILD_DIR) + "/server/pf-coordinator";
  std::string scene = std::string(PF_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.json";
  std::string json_out;
};

// Run `run` of the coordinator on `data`: its output in DIR/coordinator<run>.out and .log.
CoordinatorProcess StartCoordinator(const std::string& bin, const fs::path& dir, const fs::path& data,
                                    int run) {
  return CoordinatorProcess(bin, data, dir / ("coordinator" + std::to_string(run) + ".out"),
                            dir / ("coordinator" + std::to_string(run) + ".log"), 60);
}

std::unique_ptr<grpc::ClientContext> Ctx(double seconds = 600) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000)));
  return ctx;
}

void Check(const grpc::Status& st, const char* what) {
  if (!st.ok()) throw std::runtime_error(std::string(what) + ": " + st.error_message());
}

double DatabaseMiB(const fs::path& data) {
  double bytes = 0;
  for (const char* name : {"coordinator.db", "coordinator.db-wal"}) {
    std::error_code ec;
    const auto size = fs::file_size(data / name, ec);
    if (!ec) bytes += double(size);
  }
  return bytes / (1 << 20);
}

struct Stage {
  std::string name;
  double rss = 0, hwm = 0, db = 0;
};

int Run(const Options& o) {
  const fs::path dir = fs::temp_directory_path() / ("pf-memory-bench-" + std::to_string(getpid()));
  const fs::path data = dir / "data";
  fs::create_directories(dir);
  std::vector<Stage> stages;
  double submit_seconds = 0;
  std::string job_id;
  {
    CoordinatorProcess coordinator = StartCoordinator(o.coordinator, dir, data, 1);
    auto render = v1::RenderService::NewStub(
        grpc::CreateChannel(coordinator.address(), grpc::InsecureChannelCredentials()));
    v1::UploadSceneRequest up;
    const SceneBundle bundle = CollectBundle(o.scene);
    BundleToProto(bundle, up.mutable_bundle());
    v1::UploadSceneResponse up_resp;
    Check(render->UploadScene(Ctx().get(), up, &up_resp), "UploadScene");
    auto stage = [&](const std::string& name) {
      stages.push_back({name, coordinator.MiB("VmRSS"), coordinator.MiB("VmHWM"), DatabaseMiB(data)});
    };
    stage("started");

    v1::SubmitJobRequest sub;
    *sub.mutable_spec() = test_util::LargestJobSpec(up_resp.scene_hash(), 1);
    v1::SubmitJobResponse sub_resp;
    submit_seconds = TimeIt([&] { Check(render->SubmitJob(Ctx().get(), sub, &sub_resp), "SubmitJob"); });
    job_id = sub_resp.job_id();
    stage("submitted");

    v1::CancelJobRequest cancel;
    cancel.set_job_id(job_id);
    v1::CancelJobResponse cancel_resp;
    Check(render->CancelJob(Ctx().get(), cancel, &cancel_resp), "CancelJob");
    // The flush of the cancellation: until the database has stopped growing for 2 s (at most 120 s).
    double last = -1;
    for (int stable = 0, i = 0; stable < 20 && i < 1200; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      const double now = DatabaseMiB(data);
      stable = now == last ? stable + 1 : 0;
      last = now;
    }
    stage("cancelled");
  }
  {
    CoordinatorProcess coordinator = StartCoordinator(o.coordinator, dir, data, 2);
    auto render = v1::RenderService::NewStub(
        grpc::CreateChannel(coordinator.address(), grpc::InsecureChannelCredentials()));
    v1::ListJobsRequest list;
    list.set_include_finished(true);
    v1::ListJobsResponse list_resp;
    Check(render->ListJobs(Ctx().get(), list, &list_resp), "ListJobs");
    if (list_resp.jobs_size() != 1 || list_resp.jobs(0).job_id() != job_id ||
        list_resp.jobs(0).state() != v1::JOB_STATE_CANCELLED)
      throw std::runtime_error("after the restart the cancelled job is not listed as cancelled");
    stages.push_back({"restarted", coordinator.MiB("VmRSS"), coordinator.MiB("VmHWM"), DatabaseMiB(data)});
  }

  nlohmann::json out;
  out["coordinator"] = o.coordinator;
  out["tasks"] = 1 << 20;
  out["submit_seconds"] = submit_seconds;
  for (const Stage& s : stages)
    out["stages"].push_back(
        {{"stage", s.name}, {"vm_rss_mib", s.rss}, {"vm_hwm_mib", s.hwm}, {"db_mib", s.db}});
  std::printf("%s\n\n", out.dump(2).c_str());
  std::printf("one job of 2^20 tasks; SubmitJob took %.2f s\n", submit_seconds);
  std::printf("%-10s %10s %10s %10s\n", "stage", "VmRSS MiB", "VmHWM MiB", "db MiB");
  for (const Stage& s : stages)
    std::printf("%-10s %10.1f %10.1f %10.1f\n", s.name.c_str(), s.rss, s.hwm, s.db);
  if (!o.json_out.empty()) std::ofstream(o.json_out) << out.dump(2) << "\n";
  std::error_code ec;
  fs::remove_all(dir, ec);
  return 0;
}

}  // namespace
}  // namespace pf::bench

int main(int argc, char** argv) {
  pf::bench::Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--coordinator" && i + 1 < argc) {
      o.coordinator = argv[++i];
    } else if (a == "--json-out" && i + 1 < argc) {
      o.json_out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: coordinator_memory_bench [--coordinator PATH] [--json-out FILE]\n");
      return 2;
    }
  }
  try {
    return pf::bench::Run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "coordinator_memory_bench: %s\n", e.what());
    return 1;
  }
}
