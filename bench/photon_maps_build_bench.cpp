// A local photon-map build, PhotonMaps::Build (common/photon/photon_maps.h) as `pf render` and the
// worker call it: time and peak memory of whole builds, so that two versions of the build can be
// compared (run the binary of each, interleaved: the machines are shared and noisy).
//
// Cases: the default job's Cornell-box map (Monte Carlo direct light: global map only), the same
// with PhotonDirect and occlusion testing (direct map, light ids and origins, §4.2.3 / §4.1.1),
// and the Cornell sphere (a caustic map, §2.1) with brute-force caustic splitting (§4.6.1).
// Per case and repetition: wall time, process CPU time (all threads) and the peak resident memory
// the build added (VmHWM reset through /proc/self/clear_refs before each build, minus the resident
// memory before it). Prints the medians and the SHA-256 of the maps' bytes with the timings zeroed
// (stored power kept), so that two versions can be checked to build the same maps byte for byte.
//
//   build/bench/photon_maps_build_bench [--photons 1000000] [--threads 2] [--repeats 5] [--json out.json]
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "bench/bench_stats.h"
#include "common/core/sha256.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/render/job_render_settings.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"

namespace {

using namespace pf;

// A field of /proc/self/status in kB ("VmRSS", "VmHWM").
double StatusMb(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string prefix = std::string(field) + ":";
  while (std::getline(in, line))
    if (line.rfind(prefix, 0) == 0) return std::stod(line.substr(prefix.size())) / 1024.0;
  return 0;
}

// Resets VmHWM to the current resident size (Linux ≥ 4.0); false if not allowed.
bool ResetPeak() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  return bool(out);
}

struct Case {
  const char* name;
  const char* scene;
  std::optional<DirectLightMode> direct;
  bool occlusion = false;
  uint32_t split = 1;
};

int Run(uint64_t photons, int threads, int repeats, const std::string& json_path) {
  const Case cases[] = {{"cornell-box", "cornell-box", std::nullopt},
                        {"cornell-box photon-direct", "cornell-box", DirectLightMode::kPhotonDirect, true},
                        {"cornell-sphere split 4", "cornell-sphere", std::nullopt, false, 4}};
  nlohmann::json out;
  out["photons"] = photons;
  out["threads"] = threads;
  out["repeats"] = repeats;
  std::printf("PhotonMaps::Build, %llu photons, %d threads, median of %d\n", (unsigned long long)photons,
              threads, repeats);
  std::printf("%-28s %9s %9s %10s %10s  %s\n", "case", "wall s", "cpu s", "peak+ MB", "stored",
              "maps sha256");
  for (const Case& c : cases) {
    const SceneRuntime scene(LoadScene(bench::SceneManifest(c.scene)));
    JobRenderSettings s;
    s.photons = photons;
    s.direct = c.direct;
    s.occlusion_test = c.occlusion;
    s.caustic_split = c.split;
    PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
    mo.tracing.threads = threads;
    std::vector<double> wall, cpu, peak;
    std::string digest;
    uint64_t stored = 0;
    for (int r = 0; r < repeats; ++r) {
      const bool reset = ResetPeak();
      const double before = StatusMb("VmRSS");
      PhotonMaps maps;
      const double w = bench::TimeIt([&] {
        cpu.push_back(bench::CpuTimeIt([&] { maps = PhotonMaps::Build(scene.accel, scene.lights, mo); }));
      });
      wall.push_back(w);
      peak.push_back(reset ? StatusMb("VmHWM") - before : 0.0);
      maps.stats.trace_seconds = maps.stats.build_seconds = 0;
      stored = maps.stats.stored_global + maps.stats.stored_caustic + maps.stats.stored_direct;
      const std::string d = Sha256Hex(SerializePhotonMaps(maps));
      if (!digest.empty() && d != digest) {
        std::fprintf(stderr, "%s: repetition %d built different maps\n", c.name, r);
        return 1;
      }
      digest = d;
    }
    std::printf("%-28s %9.3f %9.3f %10.1f %10llu  %s\n", c.name, bench::Median(wall), bench::Median(cpu),
                bench::Median(peak), (unsigned long long)stored, digest.substr(0, 16).c_str());
    out["cases"][c.name] = {{"wall_seconds", bench::Median(wall)},
                            {"cpu_seconds", bench::Median(cpu)},
                            {"peak_added_mb", bench::Median(peak)},
                            {"stored", stored},
                            {"maps_sha256", digest},
                            {"wall_all", wall},
                            {"cpu_all", cpu},
                            {"peak_all", peak}};
  }
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(2) << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  uint64_t photons = 1000000;
  int threads = 2, repeats = 5;
  std::string json;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool has_value = i + 1 < argc;
    if (a == "--photons" && has_value) {
      photons = std::stoull(argv[++i]);
    } else if (a == "--threads" && has_value) {
      threads = std::stoi(argv[++i]);
    } else if (a == "--repeats" && has_value) {
      repeats = std::stoi(argv[++i]);
    } else if (a == "--json" && has_value) {
      json = argv[++i];
    } else {
      std::fprintf(stderr, "usage: %s [--photons 1000000] [--threads 2] [--repeats 5] [--json out.json]\n",
                   argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  return Run(photons, threads, repeats, json);
}
