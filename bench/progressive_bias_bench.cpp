// How well the progressive plan's error estimate (common/plan/progressive_bias.h: per-map noise
// plus the bias fitted from the passes' radii) tracks the true error against an independent
// path-traced reference, and what the estimate costs. Per scene: one progressive job of up to
// --passes passes rendered here task by task with the farm's Accumulator (ExecuteTask, as
// RenderPlanLocally does); at 4, 8, 16, ... passes the estimates against
//   true_rmse    RMS over pixels outside the emitters' mask (image_diff.h) of the luminance error
//   true_block   RMS over the indicator's 16x16 blocks of the mean luminance error (low frequencies)
// and the time of Accumulator::Estimates() against the time of the pass (CPU time, this thread).
//
//   build/bench/progressive_bias_bench [--scenes cornell-box,cornell-sphere] [--passes 128]
//                                      [--photons 10000] [--k 50] [--threads 2] [--json out.json]
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "common/camera/camera.h"
#include "common/image/exr_io.h"
#include "common/image/image_diff.h"
#include "common/plan/accumulator.h"
#include "common/plan/task_executor.h"
#include "common/render/emitter_coverage.h"
#include "common/scene/scene_loader.h"

using namespace pf;

namespace {

double CpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

struct TrueError {
  double rmse = 0, block = 0;
};

TrueError Measure(const Image& img, const Image& ref, const std::vector<uint8_t>& excluded) {
  TrueError t;
  double se = 0;
  size_t n = 0;
  for (size_t i = 0; i < img.size(); ++i) {
    if (excluded[i]) continue;
    const double d = double(img[i].Luminance()) - double(ref[i].Luminance());
    se += d * d;
    ++n;
  }
  t.rmse = std::sqrt(se / double(std::max<size_t>(n, 1)));
  const int side = int(kBiasBlockSide), bx = (img.width() + side - 1) / side,
            by = (img.height() + side - 1) / side;
  double bse = 0;
  for (int j = 0; j < by; ++j)
    for (int i = 0; i < bx; ++i) {
      double d = 0;
      int count = 0;
      for (int y = j * side; y < std::min(img.height(), (j + 1) * side); ++y)
        for (int x = i * side; x < std::min(img.width(), (i + 1) * side); ++x, ++count)
          d += double(img.at(x, y).Luminance()) - double(ref.at(x, y).Luminance());
      bse += (d / count) * (d / count);
    }
  t.block = std::sqrt(bse / (bx * by));
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  std::string scenes_arg = "cornell-box,cornell-sphere", json_path;
  uint32_t passes = 128;
  uint64_t photons = 10000;
  int k = 50, threads = 2;
  const std::map<std::string, std::function<void(const std::string&)>> flags = {
      {"--scenes", [&](const std::string& v) { scenes_arg = v; }},
      {"--passes", [&](const std::string& v) { passes = uint32_t(std::max(4, std::stoi(v))); }},
      {"--photons", [&](const std::string& v) { photons = std::stoull(v); }},
      {"--k", [&](const std::string& v) { k = std::stoi(v); }},
      {"--threads", [&](const std::string& v) { threads = std::stoi(v); }},
      {"--json", [&](const std::string& v) { json_path = v; }}};
  for (int i = 1; i < argc; i += 2) {
    const auto flag = flags.find(argv[i]);
    if (flag == flags.end() || i + 1 >= argc) {
      std::fprintf(
          stderr,
          "usage: %s [--scenes a,b] [--passes N] [--photons N] [--k K] [--threads T] [--json out.json]\n",
          argv[0]);
      return 2;
    }
    flag->second(argv[i + 1]);
  }
  spdlog::set_level(spdlog::level::warn);
  nlohmann::json rows = nlohmann::json::array();
  std::printf(
      "| scene | passes | noise est | bias est | error est | true RMSE | est/true | true block | bias/block "
      "| estimate ms | pass ms |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::stringstream names(scenes_arg);
  for (std::string name; std::getline(names, name, ',');) {
    const std::string manifest = bench::SceneManifest(name);
    const std::string ref_path = std::string(PF_SOURCE_DIR) + "/scenes/" + name + "/reference-256.exr";
    const Image reference = ReadExr(ref_path);
    const SceneRuntime scene(LoadScene(manifest));
    CameraSpec spec = scene.description.cameras.empty() ? DefaultCamera(scene.description)
                                                        : scene.description.cameras.front();
    spec.width = reference.width();
    spec.height = reference.height();
    const Camera camera(spec, scene.description.origin);
    const std::vector<uint8_t> excluded =
        EmitterExclusionMask(EmitterCoverage(scene.accel, camera), spec.width, spec.height);
    JobRenderSettings settings;
    settings.integrator = IntegratorKind::kPhotonMap;
    settings.photons = photons;
    settings.k = k;
    const PlanSpec plan{.kind = PlanKind::kProgressive, .maps = passes, .samples_per_pixel = 1};
    Accumulator acc(plan, spec.width, spec.height, settings.progressive_alpha);
    PhotonMapCache cache(1);
    double pass_cpu = 0;
    uint32_t next_report = kMinPassesForBias;
    for (const TaskSpec& task : ExpandPlan(plan, spec.width, spec.height, 1)) {
      const double c0 = CpuSeconds();
      const TaskOutput out = ExecuteTask(scene, "bench", spec, settings, task, threads, &cache);
      pass_cpu += CpuSeconds() - c0;
      acc.AddValidated(task, out.pixel_indices, out.rgb_sums, out.samples);
      const uint32_t done = uint32_t(task.map_index) + 1;
      if (done != next_report) continue;
      next_report *= 2;
      const double e0 = CpuSeconds();
      const ErrorEstimates est = acc.Estimates();
      const double estimate_cpu = CpuSeconds() - e0;
      const TrueError truth = Measure(acc.Resolve(), reference, excluded);
      const nlohmann::json row = {{"scene", name},
                                  {"passes", done},
                                  {"photons_per_pass", photons},
                                  {"k", k},
                                  {"noise_estimate", est.noise},
                                  {"bias_estimate", est.bias},
                                  {"error_estimate", est.error},
                                  {"true_rmse", truth.rmse},
                                  {"true_block_rmse", truth.block},
                                  {"estimate_cpu_ms", 1e3 * estimate_cpu},
                                  {"pass_cpu_ms", 1e3 * pass_cpu / done}};
      rows.push_back(row);
      std::printf("| %s | %u | %.5f | %.5f | %.5f | %.5f | %.2f | %.5f | %.2f | %.2f | %.1f |\n",
                  name.c_str(), done, est.noise, est.bias, est.error, truth.rmse, est.error / truth.rmse,
                  truth.block, est.bias / truth.block, 1e3 * estimate_cpu, 1e3 * pass_cpu / done);
      std::fflush(stdout);
    }
  }
  if (!json_path.empty()) std::ofstream(json_path) << nlohmann::json{{"rows", rows}}.dump(2) << "\n";
  return 0;
}
