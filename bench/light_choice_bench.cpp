// The light choice of the path tracer's next-event estimation (common/lights/light_choice.h): the
// error of the path tracer at equal samples for several β (β = 0: by power alone, the thesis's
// rule; β > 0: that share uniform over the lights), side by side in one run, on the shipped scenes
// with more than one light and a converged reference. Every row renders the same pixel samples
// (seeds 1..repeats); only the shadow rays go to other lights, so the CPU time is printed to show
// it hardly changes; the errors are `pf diff --scene`'s (display-clamped, masked away from the emitters,
// 4x4-block low-frequency) against the reference, medians over the seeds.
//
//   build/bench/light_choice_bench [--spp 32] [--repeats 2] [--betas 0,0.25,0.5,0.75]
//                                  [--scenes scene8,scene10,bathroom,conference,blender-studio] [--json
//                                  out.json]
#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "bench/bench_stats.h"
#include "common/image/exr_io.h"
#include "common/image/image_diff.h"
#include "common/render/emitter_coverage.h"
#include "common/render/path_tracer.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"

using namespace pf;

namespace {

// The converged reference of each scene (scenes/<name>/...), as the other benchmarks use them.
const std::map<std::string, std::string> kReferences = {{"scene8", "reference-320.exr"},
                                                        {"scene10", "reference-320.exr"},
                                                        {"bathroom", "reference-160.exr"},
                                                        {"conference", "reference-160.exr"},
                                                        {"blender-studio", "reference-128x96.exr"}};

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string item; std::getline(in, item, ',');) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  uint32_t spp = 32;
  int repeats = 2;
  std::string betas = "0,0.25,0.5,0.75", scenes = "scene8,scene10,bathroom,conference,blender-studio",
              json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--spp")
      spp = uint32_t(std::stoul(next()));
    else if (a == "--repeats")
      repeats = std::max(1, std::stoi(next()));
    else if (a == "--betas")
      betas = next();
    else if (a == "--scenes")
      scenes = next();
    else if (a == "--json")
      json_path = next();
    else {
      std::fprintf(
          stderr, "usage: %s [--spp S] [--repeats N] [--betas B,...] [--scenes NAME,...] [--json out.json]\n",
          argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  double load[3] = {0, 0, 0};
  getloadavg(load, 3);
  std::printf("path tracer light choice: %u spp, medians over seeds 1..%d, process CPU s (load %.1f)\n", spp,
              repeats, load[0]);
  std::printf("%-15s %6s %7s %8s %10s %10s %10s %9s %9s %9s\n", "scene", "lights", "beta", "CPU s", "display",
              "masked", "lowfreq", "disp/b0", "mask/b0", "low/b0");
  nlohmann::json out = nlohmann::json::array();
  for (const std::string& name : Split(scenes)) {
    const auto reference_file = kReferences.find(name);
    if (reference_file == kReferences.end()) {
      std::fprintf(stderr, "no reference known for scene '%s'\n", name.c_str());
      return 2;
    }
    const std::string manifest = bench::SceneManifest(name);
    const Image reference =
        ReadExr(std::string(PF_SOURCE_DIR) + "/scenes/" + name + "/" + reference_file->second);
    const SceneDescription scene = LoadScene(manifest);
    const EmbreeScene accel(scene);
    const LightSampler lights(accel);
    CameraSpec spec = scene.cameras.front();
    spec.width = reference.width();
    spec.height = reference.height();
    const Camera camera(spec, scene.origin);
    const std::vector<uint8_t> excluded =
        EmitterExclusionMask(EmitterCoverage(accel, camera), spec.width, spec.height);
    std::map<std::string, double> base;
    for (const std::string& beta_text : Split(betas)) {
      PathTracerOptions options;
      options.nee_uniform_fraction = std::stof(beta_text);
      const PathTracer tracer(accel, lights, options);
      std::vector<double> cpu, display, masked, lowfreq;
      for (int r = 1; r <= repeats; ++r) {
        Image image;
        cpu.push_back(bench::CpuTimeIt(
            [&] { image = RenderImage(tracer, camera, RenderOptions{.spp = spp, .seed = uint64_t(r)}); }));
        const ImageDiffStats d = CompareImages(image, reference, &excluded);
        display.push_back(d.rmse_display);
        masked.push_back(d.rmse_masked);
        lowfreq.push_back(d.rmse_lowfreq);
      }
      const double m_cpu = bench::Median(cpu), m_display = bench::Median(display),
                   m_masked = bench::Median(masked), m_lowfreq = bench::Median(lowfreq);
      if (base.empty()) base = {{"display", m_display}, {"masked", m_masked}, {"lowfreq", m_lowfreq}};
      std::printf("%-15s %6zu %7s %8.2f %10.5f %10.5f %10.5f %9.2f %9.2f %9.2f\n", name.c_str(),
                  lights.num_lights(), beta_text.c_str(), m_cpu, m_display, m_masked, m_lowfreq,
                  m_display / base["display"], m_masked / base["masked"], m_lowfreq / base["lowfreq"]);
      out.push_back({{"scene", name},
                     {"lights", lights.num_lights()},
                     {"beta", options.nee_uniform_fraction},
                     {"spp", spp},
                     {"cpu_s", cpu},
                     {"rmse_display", display},
                     {"rmse_masked", masked},
                     {"rmse_lowfreq", lowfreq},
                     {"median_cpu_s", m_cpu},
                     {"median_rmse_display", m_display},
                     {"median_rmse_masked", m_masked},
                     {"median_rmse_lowfreq", m_lowfreq},
                     {"load_average", load[0]}});
    }
  }
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(1) << "\n";
  return 0;
}
