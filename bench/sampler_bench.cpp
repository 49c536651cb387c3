// The samplers' cost (docs/renderer.md, "Sampling and determinism"): nanoseconds per 1-D and 2-D number for
// the independent and the Sobol sampler, and the renderer's time per sample with each (path tracer and
// photon-map integrator on the Cornell box), measured side by side in one run: the variants alternate within
// every repeat, and the medians and their ratio are printed as a table and JSON.
//
//   build/bench/sampler_bench [--repeats 7] [--res 128] [--spp 8] [--integrator path|photonmap]
//                             [--json out.json]     (--integrator: time only that one)
//                             [--clock wall|cpu] [--profile-kind sobol|independent]
//   --clock cpu times the renders by the process's CPU time (the renders are single-threaded):
//   on a loaded machine it leaves out the waits for a core that wall time counts.
//   --profile-kind renders with that sampler only (no ratio): run it under callgrind or perf to
//   count what one sampler's samples cost, e.g.
//   valgrind --tool=callgrind build/bench/sampler_bench --repeats 1 --res 32 --spp 8
//       --integrator photonmap --profile-kind sobol     (one command line)
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "bench/bench_stats.h"
#include "common/camera/camera.h"
#include "common/plan/task_executor.h"
#include "common/render/path_tracer.h"
#include "common/render/renderer.h"
#include "common/sampling/sample_layout.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

using bench::Median;
using bench::TimeIt;

// ns per number: `samples` pixel samples (64 per pixel), each asking `slots` slots once (as a
// path does); slots past sobol::kPixelSeedSlots hash their seeds per number.
double NsPerNumber(SamplerKind kind, bool two_d, uint32_t samples, uint32_t slots, float* sink) {
  float acc = 0;
  const double s = TimeIt([&] {
    for (uint32_t i = 0; i < samples; i += 64) {
      // As the renderer: the pixel's keys and slot seeds once per pixel (64 samples).
      const PixelStream pixel(kind, 7, i >> 6);
      for (uint32_t s = 0; s < 64; ++s) {
        Sampler sampler = Sampler::ForPixelSample(pixel, s);
        for (uint32_t d = 0; d < slots; ++d) {
          if (two_d) {
            const Sample2 p = sampler.Get2D(d);
            acc += p.u + p.v;
          } else {
            acc += sampler.Get1D(d);
          }
        }
      }
    }
  });
  *sink += acc;
  return s * 1e9 / (double(samples) * slots);
}

int Run(int repeats, int res, uint32_t spp, const std::string& only, const std::string& json_path,
        std::optional<SamplerKind> profile_kind, bool cpu_clock) {
  nlohmann::json out;
  float sink = 0;
  std::printf(
      "sampler cost per number (1 thread, median of %d; the %u slots of the layout's budget per sample)\n",
      repeats, sobol::kPixelSeedSlots);
  std::printf("%-12s %10s %10s\n", "sampler", "1-D ns", "2-D ns");
  for (SamplerKind kind : {SamplerKind::kIndependent, SamplerKind::kSobol}) {
    if (profile_kind && kind != *profile_kind) continue;
    std::vector<double> one, two;
    for (int r = 0; r < repeats; ++r) {
      one.push_back(NsPerNumber(kind, false, 1 << 16, sobol::kPixelSeedSlots, &sink));
      two.push_back(NsPerNumber(kind, true, 1 << 16, sobol::kPixelSeedSlots, &sink));
    }
    std::printf("%-12s %10.2f %10.2f\n", SamplerName(kind), Median(one), Median(two));
    out["per_number"][SamplerName(kind)] = {{"ns_1d", Median(one)}, {"ns_2d", Median(two)}};
  }

  const SceneRuntime scene(LoadScene(std::string(PF_SOURCE_DIR) + "/scenes/cornell-box/cornell-box.json"));
  CameraSpec spec = scene.description.cameras.front();
  spec.width = spec.height = res;
  const Camera camera(spec, scene.description.origin);  // into the scene's frame (scene_frame.h)
  std::vector<uint32_t> pixels(size_t(res) * res);
  std::iota(pixels.begin(), pixels.end(), 0u);
  const PathTracer path(scene.accel, scene.lights);
  JobRenderSettings settings;
  settings.photons = 50000;
  settings = settings.Resolved(scene.description);
  PhotonMapsOptions mo = settings.MapsOptions();
  mo.tracing.threads = 1;
  const PhotonMaps maps = PhotonMaps::Build(scene.accel, scene.lights, mo);
  const PhotonMapIntegrator photonmap(scene.accel, &scene.lights, maps,
                                      settings.IntegratorOptions(scene.accel.bounds()));
  std::printf("\nrenderer, Cornell box %dx%d, %u spp, 1 thread: microseconds per sample (%s, median of %d)\n",
              res, res, spp, cpu_clock ? "process CPU time" : "wall time", repeats);
  std::printf("%-10s %12s %12s %8s\n", "integrator", "independent", "sobol", "ratio");
  for (const Integrator* integrator :
       {static_cast<const Integrator*>(&path), static_cast<const Integrator*>(&photonmap)}) {
    if (!only.empty() && only != integrator->name()) continue;
    std::vector<double> t[2];
    for (int r = 0; r < repeats; ++r)
      for (int k = 0; k < 2; ++k) {
        const SamplerKind kind = k == 0 ? SamplerKind::kIndependent : SamplerKind::kSobol;
        if (profile_kind && kind != *profile_kind) {
          t[k].push_back(0.0);
          continue;
        }
        std::vector<Rgb> sums(pixels.size());
        auto render = [&] {
          RenderPixels(*integrator, camera, pixels, 0, spp, 1, 1, sums, nullptr, nullptr, kind);
        };
        t[k].push_back((cpu_clock ? bench::CpuTimeIt(render) : TimeIt(render)) * 1e6 /
                       (double(pixels.size()) * spp));
      }
    const double ind = Median(t[0]), sob = Median(t[1]);
    std::printf("%-10s %12.3f %12.3f %8.3f\n", integrator->name(), ind, sob, sob / ind);
    out["renderer"][integrator->name()] = {{"us_per_sample_independent", ind},
                                           {"us_per_sample_sobol", sob},
                                           {"ratio_sobol_over_independent", sob / ind}};
  }
  out["config"] = {{"repeats", repeats},
                   {"res", res},
                   {"spp", spp},
                   {"clock", cpu_clock ? "cpu" : "wall"},
                   {"sink", sink}};
  std::printf("\n%s\n", out.dump(1).c_str());
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(1) << "\n";
  return 0;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  int repeats = 7, res = 128;
  uint32_t spp = 8;
  std::string json, only;
  std::optional<pf::SamplerKind> profile_kind;
  bool cpu_clock = false;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--repeats")
      repeats = std::stoi(v);
    else if (k == "--res")
      res = std::stoi(v);
    else if (k == "--spp")
      spp = uint32_t(std::stoul(v));
    else if (k == "--json")
      json = v;
    else if (k == "--integrator")
      only = v;
    else if (k == "--clock" && (v == "cpu" || v == "wall"))
      cpu_clock = v == "cpu";
    else if (k == "--profile-kind" && pf::ParseSamplerKind(v))
      profile_kind = pf::ParseSamplerKind(v);
    else {
      std::fprintf(
          stderr,
          "usage: %s [--repeats 7] [--res 128] [--spp 8] [--integrator path|photonmap] [--json out.json]\n"
          "          [--clock wall|cpu] [--profile-kind sobol|independent]\n",
          argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  return pf::Run(repeats, res, spp, only, json, profile_kind, cpu_clock);
}
