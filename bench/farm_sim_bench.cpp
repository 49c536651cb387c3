// farm_sim_bench: the REAL coordinator (a pf-coordinator process on 127.0.0.1:0, durable
// acknowledgements as by default) driven by N simulated workers — threads, each with its own
// gRPC connection, issuing the real LeaseTask / ExtendLease / CompleteTask calls with result
// payloads of the real size (3 floats per pixel of the task). A simulated worker "renders" by
// sleeping for a task time drawn from a measured run (the leased → merged intervals in the log of
// a real coordinator, --task-log), scaled by --time-scale so that the sweep fits in minutes.
//
// Per N = 1, 2, 4, …, 256 (median of --repeat runs):
//   coordinator CPU per task   utime + stime of the coordinator process (/proc/<pid>/stat) over
//                              the job, divided by its tasks — CPU, not wall: the machine is loaded
//   bytes per task             the serialized LeaseTask + CompleteTask (+ ExtendLease) requests
//                              and responses (protobuf bytes; HTTP/2 and TCP framing not counted)
//   tasks/s                    tasks / wall seconds of the job
//   speed-up                   Σ simulated task times / wall (the ideal is N)
// Then a saturation run (task time 0, --saturation-workers) for the tasks/s the coordinator
// sustains, and the projected speed-up vs N: min(N, mean task time / CPU per task), the
// coordinator's lock being serial (its O(pixels) merge runs beside it).
//
//   build/bench/farm_sim_bench --task-log coordinator.log --json-out docs/results/farm-sim.json
// (docs/results/farm-sim.md has the command that made the task log.)

#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bench/bench_stats.h"
#include "bench/coordinator_process.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.grpc.pb.h"
#include "photonfarm_version.h"
#include "proto/convert.h"

namespace pf::bench {
namespace {
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string coordinator = std::string(PF_BUILD_DIR) + "/server/pf-coordinator";
  std::string scene = std::string(PF_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.json";
  std::string task_log;
  std::string json_out;
  std::vector<int> workers = {1, 2, 4, 8, 16, 32, 64, 128, 256};
  int tasks_per_worker = 8;
  double time_scale = 0.1;
  int repeat = 3;
  int res = 256;  // 16 tiles of 64² per map: 8 tasks per worker need N / 2 maps
  int tile = 64;
  int saturation_workers = 32;
  int saturation_tasks = 2048;
};

// The leased → merged interval of every task of a real coordinator's log (spdlog lines
// "[date time.ms] [info] job J task T: leased to W" and "job J task T: merged").
std::vector<double> TaskTimesFromLog(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("--task-log: cannot read " + path);
  const std::regex line(
      R"(^\[\d+-\d+-\d+ (\d+):(\d+):(\d+)\.(\d+)\] \[\w+\] job (\S+) task (\d+): (leased|merged))");
  std::map<std::string, double> leased;
  std::vector<double> out;
  std::string s;
  while (std::getline(in, s)) {
    std::smatch m;
    if (!std::regex_search(s, m, line)) continue;
    const double t = std::stod(m[1]) * 3600 + std::stod(m[2]) * 60 + std::stod(m[3]) + std::stod(m[4]) / 1000;
    const std::string key = m[5].str() + "/" + m[6].str();
    if (m[7] == "leased") {
      leased[key] = t;
    } else if (auto it = leased.find(key); it != leased.end()) {
      out.push_back(t - it->second);
      leased.erase(it);
    }
  }
  if (out.empty()) throw std::runtime_error("--task-log: no leased/merged task pairs in " + path);
  return out;
}

std::shared_ptr<grpc::Channel> Connect(const std::string& address, int id) {
  grpc::ChannelArguments args;
  args.SetInt("pf.sim.worker", id);  // distinct arguments: a connection of its own, as a real worker
  args.SetMaxReceiveMessageSize(64 << 20);
  args.SetMaxSendMessageSize(64 << 20);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

std::unique_ptr<grpc::ClientContext> Ctx(double seconds = 60) {
  auto ctx = std::make_unique<grpc::ClientContext>();
  ctx->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(int64_t(seconds * 1000)));
  return ctx;
}

struct RunResult {
  int workers = 0;
  uint64_t tasks = 0;
  double wall = 0, coordinator_cpu = 0, simulated_work = 0, bytes = 0;
  double cpu_ms_per_task() const { return 1000 * coordinator_cpu / double(tasks); }
  double bytes_per_task() const { return bytes / double(tasks); }
  double tasks_per_second() const { return double(tasks) / wall; }
  double speedup() const { return simulated_work / wall; }
};

// One job of `tasks` 64×64-tile tasks (multiple maps over a res × res image) run by n simulated
// workers whose task times are drawn from `times` × scale.
RunResult RunOnce(const Options& o, int n, uint64_t tasks_wanted, const std::vector<double>& times,
                  double scale, const fs::path& dir, uint64_t seed) {
  fs::create_directories(dir);
  CoordinatorProcess coordinator(o.coordinator, dir / "data", dir / "coordinator.out",
                                 dir / "coordinator.log", 30);
  auto channel = Connect(coordinator.address(), -1);
  auto render = v1::RenderService::NewStub(channel);

  v1::UploadSceneRequest up;
  const SceneBundle bundle = CollectBundle(o.scene);
  BundleToProto(bundle, up.mutable_bundle());
  v1::UploadSceneResponse up_resp;
  if (grpc::Status st = render->UploadScene(Ctx().get(), up, &up_resp); !st.ok())
    throw std::runtime_error("UploadScene: " + st.error_message());

  const uint64_t tiles_per_map = uint64_t(o.res / o.tile) * uint64_t(o.res / o.tile);
  const uint64_t maps = (tasks_wanted + tiles_per_map - 1) / tiles_per_map;
  v1::SubmitJobRequest sub;
  v1::JobSpec& spec = *sub.mutable_spec();
  spec.set_scene_hash(up_resp.scene_hash());
  spec.mutable_camera()->set_width(uint32_t(o.res));
  spec.mutable_camera()->set_height(uint32_t(o.res));
  spec.mutable_settings()->set_integrator(v1::INTEGRATOR_PHOTONMAP);
  spec.mutable_settings()->mutable_photon_map()->set_photons(1000);
  spec.mutable_settings()->mutable_photon_map()->set_k(20);
  spec.mutable_plan()->mutable_multiple_maps()->set_maps(uint32_t(maps));
  spec.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
  spec.mutable_plan()->mutable_multiple_maps()->set_tile_size(uint32_t(o.tile));
  spec.set_seed(seed);
  v1::SubmitJobResponse sub_resp;
  if (grpc::Status st = render->SubmitJob(Ctx().get(), sub, &sub_resp); !st.ok())
    throw std::runtime_error("SubmitJob: " + st.error_message());
  const uint64_t total = maps * tiles_per_map;

  std::atomic<uint64_t> completed{0};
  std::atomic<double> work{0}, bytes{0};
  std::mutex error_mu;
  std::string error;
  const double cpu0 = coordinator.CpuSeconds();
  const auto t0 = Clock::now();
  std::vector<std::thread> threads;
  for (int w = 0; w < n; ++w)
    threads.emplace_back([&, w] {
      auto stub = v1::WorkerService::NewStub(Connect(coordinator.address(), w));
      std::mt19937_64 rng(seed * 1000003 + uint64_t(w));
      const std::vector<float> payload(size_t(o.tile) * size_t(o.tile) * 3, 0.5f);
      double my_work = 0, my_bytes = 0;
      while (completed.load() < total) {
        v1::LeaseTaskRequest lreq;
        lreq.set_worker_id("sim-" + std::to_string(w));
        lreq.set_worker_version(PF_VERSION);
        lreq.set_threads(1);
        lreq.set_wait_seconds(0.5);
        v1::LeaseTaskResponse lresp;
        if (grpc::Status st = stub->LeaseTask(Ctx().get(), lreq, &lresp); !st.ok()) {
          std::lock_guard lock(error_mu);
          error = "LeaseTask: " + st.error_message();
          return;
        }
        my_bytes += double(lreq.ByteSizeLong() + lresp.ByteSizeLong());
        if (!lresp.has_task()) continue;
        const v1::Task& task = lresp.task();
        const double seconds = times[rng() % times.size()] * scale;
        my_work += seconds;
        // A real worker heartbeats every third of the lease; a task shorter than that sends none.
        const double beat = task.lease_seconds() / 3;
        for (double left = seconds; left > 0; left -= beat) {
          std::this_thread::sleep_for(std::chrono::duration<double>(std::min(left, beat)));
          if (left > beat) {
            v1::ExtendLeaseRequest ereq;
            ereq.set_lease_id(task.lease_id());
            ereq.set_progress(1 - (left - beat) / seconds);
            v1::ExtendLeaseResponse eresp;
            stub->ExtendLease(Ctx().get(), ereq, &eresp);
            my_bytes += double(ereq.ByteSizeLong() + eresp.ByteSizeLong());
          }
        }
        v1::CompleteTaskRequest creq;
        creq.set_lease_id(task.lease_id());
        *creq.mutable_rgb_sums() = {payload.begin(), payload.end()};
        creq.mutable_stats()->set_render_seconds(seconds);
        v1::CompleteTaskResponse cresp;
        if (grpc::Status st = stub->CompleteTask(Ctx().get(), creq, &cresp); !st.ok() || !cresp.merged()) {
          std::lock_guard lock(error_mu);
          error = "CompleteTask: " + (st.ok() ? std::string("not merged") : st.error_message());
          return;
        }
        my_bytes += double(creq.ByteSizeLong() + cresp.ByteSizeLong());
        completed.fetch_add(1);
      }
      work.fetch_add(my_work);
      bytes.fetch_add(my_bytes);
    });
  for (std::thread& t : threads) t.join();
  RunResult r;
  r.wall = std::chrono::duration<double>(Clock::now() - t0).count();
  r.coordinator_cpu = coordinator.CpuSeconds() - cpu0;
  if (!error.empty()) throw std::runtime_error(error);
  v1::GetJobRequest get;
  get.set_job_id(sub_resp.job_id());
  v1::JobStatus status;
  render->GetJob(Ctx().get(), get, &status);
  if (status.state() != v1::JOB_STATE_SUCCEEDED || status.tasks_done() != total)
    throw std::runtime_error("the job did not succeed with every task merged: " + status.DebugString());
  r.workers = n;
  r.tasks = total;
  r.simulated_work = work.load();
  r.bytes = bytes.load();
  return r;
}

std::vector<int> ParseList(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(std::stoi(item));
  return out;
}

int Main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error(a + ": needs a value");
      return argv[++i];
    };
    if (a == "--coordinator")
      o.coordinator = next();
    else if (a == "--scene")
      o.scene = next();
    else if (a == "--task-log")
      o.task_log = next();
    else if (a == "--json-out")
      o.json_out = next();
    else if (a == "--workers")
      o.workers = ParseList(next());
    else if (a == "--tasks-per-worker")
      o.tasks_per_worker = std::stoi(next());
    else if (a == "--time-scale")
      o.time_scale = std::stod(next());
    else if (a == "--repeat")
      o.repeat = std::stoi(next());
    else if (a == "--saturation-workers")
      o.saturation_workers = std::stoi(next());
    else if (a == "--saturation-tasks")
      o.saturation_tasks = std::stoi(next());
    else {
      std::fprintf(
          stderr,
          "usage: farm_sim_bench --task-log COORDINATOR_LOG [--workers 1,2,...,256] [--tasks-per-worker 8] "
          "[--time-scale 0.1] [--repeat 3] [--saturation-workers 32] [--saturation-tasks 2048] "
          "[--coordinator BIN] [--scene MANIFEST] [--json-out FILE]\n");
      return 2;
    }
  }
  if (o.task_log.empty()) {
    std::fprintf(stderr, "farm_sim_bench: --task-log is required (a real coordinator's log)\n");
    return 2;
  }
  const std::vector<double> times = TaskTimesFromLog(o.task_log);
  double mean_time = 0;
  for (double t : times) mean_time += t;
  mean_time /= double(times.size());
  const fs::path dir = fs::temp_directory_path() / ("pf_farm_sim_" + std::to_string(getpid()));
  const uint64_t payload_bytes = uint64_t(o.tile) * uint64_t(o.tile) * 12;
  std::fprintf(stderr, "task times: %zu measured, mean %.3f s, median %.3f s; scaled by %.3g\n", times.size(),
               mean_time, Median(times), o.time_scale);

  nlohmann::json out;
  out["task_times"] = {{"source", o.task_log},
                       {"count", times.size()},
                       {"mean_s", mean_time},
                       {"median_s", Median(times)},
                       {"time_scale", o.time_scale}};
  out["task"] = {{"pixels", o.tile * o.tile}, {"result_bytes", payload_bytes}, {"image", o.res}};
  std::vector<nlohmann::json> rows;
  std::vector<double> cpu_per_task_all;
  uint64_t run_id = 0;
  for (int n : o.workers) {
    std::vector<double> cpu, bytes, tps, speedup, wall;
    uint64_t tasks = 0;
    for (int rep = 0; rep < o.repeat; ++rep) {
      const uint64_t wanted = uint64_t(o.tasks_per_worker) * uint64_t(n);
      ++run_id;
      const RunResult r = RunOnce(o, n, wanted, times, o.time_scale, dir / std::to_string(run_id), run_id);
      tasks = r.tasks;
      cpu.push_back(r.cpu_ms_per_task());
      bytes.push_back(r.bytes_per_task());
      tps.push_back(r.tasks_per_second());
      speedup.push_back(r.speedup());
      wall.push_back(r.wall);
      std::fprintf(stderr,
                   "  N=%d run %d: %llu tasks in %.2f s, coordinator %.3f ms CPU/task, speed-up %.1f\n", n,
                   rep + 1, (unsigned long long)r.tasks, r.wall, r.cpu_ms_per_task(), r.speedup());
    }
    cpu_per_task_all.push_back(Median(cpu));
    rows.push_back({{"workers", n},
                    {"tasks", tasks},
                    {"wall_s", Median(wall)},
                    {"coordinator_cpu_ms_per_task", Median(cpu)},
                    {"bytes_per_task", Median(bytes)},
                    {"tasks_per_s", Median(tps)},
                    {"speedup", Median(speedup)}});
  }
  // Saturation: no task time at all — the coordinator (and this machine's 2 cores, shared with
  // the simulated workers) is the only limit.
  std::vector<double> sat_tps, sat_cpu;
  for (int rep = 0; rep < o.repeat; ++rep) {
    ++run_id;
    const RunResult r = RunOnce(o, o.saturation_workers, uint64_t(o.saturation_tasks), times, 0.0,
                                dir / std::to_string(run_id), run_id);
    sat_tps.push_back(r.tasks_per_second());
    sat_cpu.push_back(r.cpu_ms_per_task());
  }
  fs::remove_all(dir);
  const double cpu_ms = Median(cpu_per_task_all);
  out["rows"] = rows;
  out["saturation"] = {{"workers", o.saturation_workers},
                       {"tasks", o.saturation_tasks},
                       {"tasks_per_s", Median(sat_tps)},
                       {"coordinator_cpu_ms_per_task", Median(sat_cpu)},
                       {"cpu_bound_tasks_per_s", 1000.0 / Median(sat_cpu)}};
  out["coordinator_cpu_ms_per_task"] = cpu_ms;
  std::vector<nlohmann::json> projection;
  for (int n : {1, 2, 4, 8, 16, 32, 64, 100, 128, 256, 512, 1024, 4096}) {
    const double s = std::min(double(n), mean_time / (cpu_ms / 1000));
    projection.push_back({{"workers", n}, {"speedup", s}});
  }
  out["projection"] = projection;

  std::printf("%s\n", out.dump(2).c_str());
  std::printf(
      "\nfarm_sim_bench: %d-pixel tasks (%llu-byte results), task times from %s (mean %.3f s) x %.3g; median "
      "of "
      "%d\n",
      o.tile * o.tile, (unsigned long long)payload_bytes, o.task_log.c_str(), mean_time, o.time_scale,
      o.repeat);
  std::printf("%8s %8s %9s %14s %12s %10s %10s\n", "workers", "tasks", "wall s", "coord ms/task",
              "bytes/task", "tasks/s", "speed-up");
  for (const nlohmann::json& r : rows)
    std::printf("%8d %8llu %9.2f %14.3f %12.0f %10.1f %10.1f\n", r["workers"].get<int>(),
                (unsigned long long)r["tasks"].get<uint64_t>(), r["wall_s"].get<double>(),
                r["coordinator_cpu_ms_per_task"].get<double>(), r["bytes_per_task"].get<double>(),
                r["tasks_per_s"].get<double>(), r["speedup"].get<double>());
  std::printf(
      "saturation (%d workers, no task time): %.0f tasks/s measured, %.3f ms coordinator CPU/task -> %.0f "
      "tasks/s per coordinator core\n",
      o.saturation_workers, Median(sat_tps), Median(sat_cpu), 1000.0 / Median(sat_cpu));
  std::printf("projected speed-up min(N, %.3f s / %.3f ms):", mean_time, cpu_ms);
  for (const nlohmann::json& p : projection)
    std::printf(" %d:%.0f", p["workers"].get<int>(), p["speedup"].get<double>());
  std::printf("\n");
  if (!o.json_out.empty()) std::ofstream(o.json_out) << out.dump(2) << "\n";
  return 0;
}

}  // namespace
}  // namespace pf::bench

int main(int argc, char** argv) {
  try {
    return pf::bench::Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "farm_sim_bench: %s\n", e.what());
    return 1;
  }
}
