// Photon tracing throughput: photons emitted, stored and rays traced per
// second on ONE thread (the walk is embarrassingly parallel; per-thread rates are what compare
// across machines), median of --repeats runs, next to the thesis's Table 2.1 random-walk
// times. Table + JSON.
//
//   build/bench/photon_tracing_bench [--photons 200000] [--repeats 3] [--clock wall|cpu] [--scenes a,b]
//                                  [--no-raw] [--no-floor] [--json out.json]
//
// --clock cpu times each trace by the process's CPU time instead of the wall clock: the trace
// runs on one thread, so on a shared, loaded machine this leaves out the time spent waiting for
// a core.
//
// Ratio to the raw Embree ray rate (docs/results/kernel.md: photon tracing at >= 60 % of it): around every
// trace the same process times embree_bench's incoherent secondary rays of the scene
// (bench/raw_rays.h, 5 passes over a 256² image's rays, on the same clock), once before and once
// after; each repeat's ratio is its photon rays/s over the mean of those two raw rates, and the
// table quotes the median ratio. Measured side by side like this, a slower or faster spell of
// this shared machine moves both rates (separate embree_bench runs minutes apart scattered
// by ±25 %, docs/results/kernel.md §4).
//
// Floor (columns `floor M/s`, `floor`): in the same repeat, bench/floor_walk.h's minimal photon
// walk — the same Embree wrapper and ray parts, one PCG stream instead of the Sobol sampler, no
// Bsdf lobes or caustic bookkeeping — timed the same way and divided by the same raw rate: how
// close to the raw rate a scalar, one-ray-at-a-time walk can come at all, next to the tracer's
// ratio. --no-floor leaves it out.
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "bench/bench_stats.h"
#include "bench/floor_walk.h"
#include "bench/raw_rays.h"
#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon_tracer.h"
#include "common/scene/scene_loader.h"

namespace {
long MinorFaults() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_minflt;
}
double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}
}  // namespace

int main(int argc, char** argv) {
  uint64_t photons = 200000;
  int repeats = 3;
  std::string json_path;
  bool cpu_clock = false;
  int raw_passes = 5;  // --no-raw: 0 (profile the trace alone)
  bool floor_walk = true;
  std::string only;  // --scenes a,b: a subset (e.g. one scene per `perf record`)
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--clock" && i + 1 < argc &&
        (std::string(argv[i + 1]) == "cpu" || std::string(argv[i + 1]) == "wall"))
      cpu_clock = std::string(argv[++i]) == "cpu";
    else if (a == "--scenes" && i + 1 < argc)
      only = std::string(",").append(argv[++i]).append(",");
    else if (a == "--photons" && i + 1 < argc)
      photons = std::stoull(argv[++i]);
    else if (a == "--repeats" && i + 1 < argc)
      repeats = std::max(1, std::atoi(argv[++i]));
    else if (a == "--no-raw")
      raw_passes = 0;
    else if (a == "--no-floor")
      floor_walk = false;
    else if (a == "--json" && i + 1 < argc)
      json_path = argv[++i];
    else {
      std::fprintf(stderr,
                   "usage: %s [--photons N] [--repeats R] [--clock wall|cpu] [--scenes a,b] [--no-raw] "
                   "[--no-floor] [--json out.json]\n",
                   argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  const auto scenes = pf::bench::SceneManifests({"cornell-box", "cornell-sphere", "office3"});
  nlohmann::json out = nlohmann::json::array();
  std::printf("photon tracing, 1 thread, %llu photons, median of %d runs, %s clock\n",
              (unsigned long long)photons, repeats, cpu_clock ? "cpu" : "wall");
  std::printf("%-15s %12s %12s %12s %10s %14s %12s %9s %10s %7s\n", "scene", "emitted k/s", "stored k/s",
              "rays M/s", "stored/em.", "s per 100k st.", "raw M/s", "ratio", "floor M/s", "floor");
  for (const auto& [name, path] : scenes) {
    if (!only.empty() && only.find("," + name + ",") == std::string::npos) continue;
    const pf::SceneDescription scene = pf::LoadScene(path);
    const pf::EmbreeScene accel(scene);
    const pf::LightSampler lights(accel);
    constexpr int kRawRes = 256;
    const int kRawPasses = raw_passes;
    pf::CameraSpec spec = scene.cameras.empty() ? pf::DefaultCamera(scene) : scene.cameras.front();
    spec.width = spec.height = kRawRes;
    pf::Rng raw_rng(42, 2);  // embree_bench's secondary rays
    // (Not even made under --no-raw: a profile of the trace alone need not count them.)
    const std::vector<pf::Ray> raw_rays =
        kRawPasses == 0
            ? std::vector<pf::Ray>()
            : pf::bench::IncoherentSecondaryRays(accel, pf::Camera(spec, scene.origin), kRawRes, raw_rng);
    volatile size_t sink = 0;
    const auto raw_rate = [&] {
      if (kRawPasses == 0) return 0.0;
      const auto run = [&] { sink = sink + pf::bench::IntersectAll(accel, raw_rays, kRawPasses); };
      const double t = cpu_clock ? pf::bench::CpuTimeIt(run) : pf::bench::TimeIt(run);
      return double(raw_rays.size()) * kRawPasses / t;
    };
    std::vector<double> emitted_rate, stored_rate, ray_rate, raw, ratio, floor_rate, floor_ratio;
    std::vector<double> faults, floor_faults;  // minor page faults of each run (result arrays)
    double stored_per_emitted = 0, rays_per_emitted = 0, floor_rays_per_emitted = 0,
           floor_stored_per_emitted = 0;
    // Seconds of `run` on the chosen clock; its minor page faults appended to *fault_counts.
    const auto timed = [&](const auto& run, std::vector<double>* fault_counts) {
      const long faults_before = MinorFaults();
      const double t = cpu_clock ? pf::bench::CpuTimeIt(run) : pf::bench::TimeIt(run);
      fault_counts->push_back(double(MinorFaults() - faults_before));
      return t;
    };
    for (int r = 0; r < repeats; ++r) {
      const double raw_before = raw_rate();
      const auto trace = [&] {
        pf::PhotonTracerOptions o;
        o.photons = photons;
        o.map_seed = uint64_t(r + 1);
        o.threads = 1;
        pf::PhotonTracingResult res;
        const double seconds = timed([&] { res = pf::TracePhotons(accel, lights, o); }, &faults);
        const double stored = double(res.direct.size() + res.indirect.size() + res.caustic.size());
        emitted_rate.push_back(double(res.emitted) / seconds);
        stored_rate.push_back(stored / seconds);
        ray_rate.push_back(double(res.rays) / seconds);
        stored_per_emitted = stored / double(res.emitted);
        rays_per_emitted = double(res.rays) / double(res.emitted);
      };
      const auto floor = [&] {
        pf::bench::FloorWalkResult walked;
        const auto run = [&] { walked = pf::bench::FloorWalk(accel, lights, photons, uint64_t(r + 1)); };
        const double t = timed(run, &floor_faults);  // before walked.rays is read
        floor_rate.push_back(double(walked.rays) / t);
        floor_rays_per_emitted = double(walked.rays) / double(photons);
        floor_stored_per_emitted = double(walked.photons.size()) / double(photons);
      };
      // Alternated, so that neither always runs first after the raw rays (or after the other's
      // freed arrays, which decide how many of the next run's pages fault).
      if (floor_walk && r % 2 == 1) floor();
      trace();
      if (floor_walk && r % 2 == 0) floor();
      const double raw_here = 0.5 * (raw_before + raw_rate());
      if (raw_here > 0) {
        raw.push_back(raw_here);
        ratio.push_back(ray_rate.back() / raw_here);
        if (floor_walk) floor_ratio.push_back(floor_rate.back() / raw_here);
      }
    }
    const double st = Median(stored_rate);
    const double raw_median = raw.empty() ? 0.0 : Median(raw),
                 ratio_median = ratio.empty() ? 0.0 : Median(ratio);
    const double floor_median = floor_rate.empty() ? 0.0 : Median(floor_rate),
                 floor_ratio_median = floor_ratio.empty() ? 0.0 : Median(floor_ratio);
    std::printf("%-15s %12.1f %12.1f %12.2f %10.2f %14.3f %12.2f %8.1f%% %10.2f %6.1f%%\n", name.c_str(),
                Median(emitted_rate) * 1e-3, st * 1e-3, Median(ray_rate) * 1e-6, stored_per_emitted, 1e5 / st,
                raw_median * 1e-6, 100 * ratio_median, floor_median * 1e-6, 100 * floor_ratio_median);
    out.push_back({{"scene", name},
                   {"photons_emitted", photons},
                   {"emitted_per_s", Median(emitted_rate)},
                   {"stored_per_s", st},
                   {"rays_per_s", Median(ray_rate)},
                   {"raw_rays_per_s", raw_median},
                   {"ratio_to_raw", ratio_median},
                   {"runs_rays_per_s", ray_rate},
                   {"runs_raw_rays_per_s", raw},
                   {"runs_ratio_to_raw", ratio},
                   {"floor_rays_per_s", floor_median},
                   {"floor_ratio_to_raw", floor_ratio_median},
                   {"runs_floor_rays_per_s", floor_rate},
                   {"runs_floor_ratio_to_raw", floor_ratio},
                   {"stored_per_emitted", stored_per_emitted},
                   {"rays_per_emitted", rays_per_emitted},
                   {"floor_rays_per_emitted", floor_rays_per_emitted},
                   {"floor_stored_per_emitted", floor_stored_per_emitted},
                   {"runs_minor_faults", faults},
                   {"runs_floor_minor_faults", floor_faults},
                   {"threads", 1},
                   {"clock", cpu_clock ? "cpu" : "wall"},
                   {"repeats", repeats}});
  }
  std::printf("thesis Table 2.1 (DEC Alpha 333 MHz): RandomWalk 100k photons 5 s, 700k 30 s\n");
  const std::string text = out.dump(2);
  if (!json_path.empty()) std::ofstream(json_path) << text << "\n";
  std::printf("%s\n", text.c_str());
  return 0;
}
