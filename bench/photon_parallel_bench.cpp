// Photon tracing and the left-balanced kd-tree build on 1 thread against N threads, side by
// side in one run (docs/farm.md, "Photon maps traced once": "photon tracing and balancing scale with
// threads").
//
// Default: the default farm job's map — scenes/cornell-box, 1M emitted photons, map seed 1 —
// traced with TracePhotons (common/photon/photon_tracer.h), then its direct + indirect photons
// put into a level-cycle KdTree and balanced (PrepareForQuery), as PhotonMaps::Build does for a
// global map. For every thread count and repetition (interleaved, so that load changes hit all
// variants alike): wall time and process CPU time (user + system) of each phase. Reports medians,
// the speed-up against 1 thread, and checks that every thread count yields the SAME traced photon
// arrays and the SAME balanced array (byte for byte; exits 1 otherwise).
//
// The machines are shared: the load average is printed and stored, and "cpu/wall" shows how many
// cores a phase actually got (on an idle 2-core machine a perfectly parallel phase shows 2.0).
// On a loaded machine the wall-clock speed-up says little (with autogroup scheduling a process
// gets the same share of the CPUs whatever its thread count), so each phase also records the
// on-CPU time of every thread of the process (/proc/self/task/*/schedstat, ns): the busiest
// thread's time, the "span", is what the phase's wall time would be on an idle machine (the
// calling thread does the serial parts and its share of the parallel ones; waiting is not
// counted), and span(1 thread) / span(N threads) is the speed-up that load cannot distort.
//
//   build/bench/photon_parallel_bench [--photons 1000000] [--threads 1,2] [--repeats 3]
//                                     [--scene cornell-box] [--json out.json]
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/lights/light_sampler.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon_tracer.h"
#include "common/scene/scene_loader.h"

namespace {

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// On-CPU nanoseconds of every thread of this process, by thread id.
std::map<std::string, double> ThreadCpu() {
  std::map<std::string, double> out;
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    std::ifstream in(entry.path() / "schedstat");
    double ns = 0;
    if (in >> ns) out[entry.path().filename().string()] = ns * 1e-9;
  }
  return out;
}

// The largest per-thread on-CPU time between two ThreadCpu() readings.
double Span(const std::map<std::string, double>& before, const std::map<std::string, double>& after) {
  double span = 0;
  for (const auto& [tid, seconds] : after) {
    const auto it = before.find(tid);
    span = std::max(span, seconds - (it == before.end() ? 0.0 : it->second));
  }
  return span;
}

std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
}

// FNV-1a over raw bytes: identical arrays <=> identical digests (for the report; the check
// itself compares the bytes).
uint64_t Digest(const void* data, size_t bytes) {
  uint64_t h = 1469598103934665603ull;
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

template <typename Photons>  // pf::TracedPhotons
std::vector<unsigned char> Bytes(const Photons& v) {
  // Field by field: TracedPhoton has padding bytes whose content is unspecified.
  std::vector<unsigned char> out;
  out.reserve(v.size() * 56);
  auto put = [&out](const void* p, size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    out.insert(out.end(), c, c + n);
  };
  for (const pf::TracedPhoton& p : v) {
    put(&p.position, sizeof(p.position));
    put(&p.direction, sizeof(p.direction));
    put(&p.power, sizeof(p.power));
    put(&p.origin, sizeof(p.origin));
    put(&p.light, sizeof(p.light));
    put(&p.kind, sizeof(p.kind));
  }
  return out;
}

struct Phase {
  std::vector<double> wall, cpu, span;
};

}  // namespace

int main(int argc, char** argv) {
  uint64_t photons = 1000000;
  int repeats = 3;
  std::vector<int> threads = {1, 2};
  std::string scene_name = "cornell-box", json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--photons" && i + 1 < argc) {
      photons = std::stoull(argv[++i]);
    } else if (a == "--repeats" && i + 1 < argc) {
      repeats = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--scene" && i + 1 < argc) {
      scene_name = argv[++i];
    } else if (a == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else if (a == "--threads" && i + 1 < argc) {
      threads.clear();
      std::stringstream list(argv[++i]);
      for (std::string t; std::getline(list, t, ',');) threads.push_back(std::max(1, std::stoi(t)));
    } else {
      std::fprintf(stderr,
                   "usage: %s [--photons N] [--threads 1,2] [--repeats R] [--scene NAME] [--json out.json]\n",
                   argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  const std::string path = std::string(PF_SOURCE_DIR) + "/scenes/" + scene_name + "/" + scene_name + ".json";
  const pf::SceneDescription scene = pf::LoadScene(path);
  const pf::EmbreeScene accel(scene);
  const pf::LightSampler lights(accel);
  const std::string load_before = LoadAverage();

  std::map<int, Phase> trace, balance;
  std::vector<unsigned char> reference_traced;
  std::vector<pf::Photon> reference_tree;
  uint64_t stored = 0;
  bool identical = true;
  for (int r = 0; r < repeats; ++r) {
    for (const int t : threads) {
      pf::PhotonTracerOptions o;
      o.photons = photons;
      o.map_seed = 1;
      o.threads = t;
      auto s0 = ThreadCpu();
      double w0 = Now(), c0 = CpuSeconds();
      const pf::PhotonTracingResult traced = pf::TracePhotons(accel, lights, o);
      trace[t].wall.push_back(Now() - w0);
      trace[t].cpu.push_back(CpuSeconds() - c0);
      trace[t].span.push_back(Span(s0, ThreadCpu()));

      std::vector<unsigned char> bytes = Bytes(traced.direct);
      const std::vector<unsigned char> indirect = Bytes(traced.indirect), caustic = Bytes(traced.caustic);
      bytes.insert(bytes.end(), indirect.begin(), indirect.end());
      bytes.insert(bytes.end(), caustic.begin(), caustic.end());
      if (reference_traced.empty()) reference_traced = bytes;
      identical = identical && bytes == reference_traced;

      // The balance phase: the global map of a render (direct + indirect photons), compacted to
      // 18 bytes outside the timer, then balanced into a left-balanced kd-tree.
      pf::KdTree tree;
      tree.Reserve(traced.direct.size() + traced.indirect.size());
      for (const auto* list : {&traced.direct, &traced.indirect})
        for (const pf::TracedPhoton& p : *list) tree.AddPhoton(p.position, p.direction, p.power);
      tree.set_build_threads(t);
      s0 = ThreadCpu();
      w0 = Now();
      c0 = CpuSeconds();
      tree.PrepareForQuery();
      balance[t].wall.push_back(Now() - w0);
      balance[t].cpu.push_back(CpuSeconds() - c0);
      balance[t].span.push_back(Span(s0, ThreadCpu()));
      stored = tree.size();
      const std::vector<pf::Photon> array(tree.photons().begin(), tree.photons().end());
      if (reference_tree.empty()) reference_tree = array;
      identical = identical && array.size() == reference_tree.size() &&
                  std::memcmp(array.data(), reference_tree.data(), array.size() * sizeof(pf::Photon)) == 0;
    }
  }

  const std::string load_after = LoadAverage();
  std::printf("%s, %llu photons emitted, %llu in the kd-tree, median of %d runs, load %s -> %s\n",
              scene_name.c_str(), (unsigned long long)photons, (unsigned long long)stored, repeats,
              load_before.c_str(), load_after.c_str());
  std::printf("%-8s %8s %10s %10s %9s %9s %9s %12s\n", "phase", "threads", "wall s", "speed-up", "cpu s",
              "cpu/wall", "span s", "span speed-up");
  nlohmann::json rows = nlohmann::json::array();
  for (const auto& [name, phase] : {std::pair{"trace", &trace}, std::pair{"balance", &balance}}) {
    const double base = Median((*phase)[threads.front()].wall);
    const double base_span = Median((*phase)[threads.front()].span);
    for (const int t : threads) {
      const Phase& p = (*phase)[t];
      const double wall = Median(p.wall), cpu = Median(p.cpu), span = Median(p.span);
      std::printf("%-8s %8d %10.3f %9.2fx %9.3f %9.2f %9.3f %11.2fx\n", name, t, wall, base / wall, cpu,
                  cpu / wall, span, base_span / span);
      rows.push_back({{"phase", name},
                      {"threads", t},
                      {"wall_s_median", wall},
                      {"speedup_vs_first", base / wall},
                      {"cpu_s_median", cpu},
                      {"span_s_median", span},
                      {"span_speedup_vs_first", base_span / span},
                      {"wall_s", p.wall},
                      {"cpu_s", p.cpu},
                      {"span_s", p.span}});
    }
  }
  std::printf("arrays identical for every thread count: %s (traced digest %016llx, tree digest %016llx)\n",
              identical ? "yes" : "NO",
              (unsigned long long)Digest(reference_traced.data(), reference_traced.size()),
              (unsigned long long)Digest(reference_tree.data(), reference_tree.size() * sizeof(pf::Photon)));
  const nlohmann::json out = {{"scene", scene_name},        {"photons_emitted", photons},
                              {"photons_in_tree", stored},  {"repeats", repeats},
                              {"load_before", load_before}, {"load_after", load_after},
                              {"identical", identical},     {"rows", rows}};
  const std::string text = out.dump(2);
  if (!json_path.empty()) std::ofstream(json_path) << text << "\n";
  std::printf("%s\n", text.c_str());
  return identical ? 0 : 1;
}
