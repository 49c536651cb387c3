// Convergence of the samplers against a converged reference (docs/renderer.md, "Sampling and determinism"),
// driven by bench/sampler_convergence.py. Two modes, each printing one JSON object per line:
//
//  progressive (default): renders 1, 2, 4, ... --max-spp samples per pixel in ONE progressive
//    render (samples [2^k, 2^(k+1)) are added to the sums of the first 2^k: for the Sobol sampler
//    the first 2^k samples are exactly what a 2^k-spp render uses) and prints after each power of
//    two the RMSE of the whole image, of the emitter-edge pixels (0 < emitter coverage < 1), and
//    the masked and low-frequency RMSE of pf diff (common/image/image_diff.h).
//  photon-emission (--photon-sampler): the photon-map integrator with --photons N at --spp, for
//    --maps map seeds, photon emission and scattering from the given sampler (pixels always
//    Sobol): the same metrics per map, so that quasi-random and random emission compare at fixed N.
//
//   build/bench/sampler_convergence_bench --scene S.json --reference R.exr --sampler sobol
//       [--integrator path] [--max-spp 1024] [--threads 1] [--seed 1]
//   build/bench/sampler_convergence_bench --scene S.json --reference R.exr --photon-sampler sobol
//       --photons 200000 --spp 16 --maps 4 [--standalone 1] [--threads 1]
#include <spdlog/spdlog.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "common/image/exr_io.h"
#include "common/image/image_diff.h"
#include "common/plan/task_executor.h"
#include "common/plan/task_plan.h"
#include "common/render/emitter_coverage.h"
#include "common/render/path_tracer.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

struct Args {
  std::string scene, reference, sampler = "sobol", photon_sampler, integrator = "path";
  uint32_t max_spp = 1024, spp = 16, maps = 4;
  uint64_t photons = 200000, seed = 1;
  int threads = 1;
  bool standalone = false;  // photon-emission mode: direct light from the map too (Wald 1999, §2.5)
};

struct Metrics {
  double rmse, rmse_edge, rmse_masked, rmse_lowfreq;
};

Metrics Measure(const Image& image, const Image& reference, const std::vector<uint8_t>& edge,
                const std::vector<uint8_t>& excluded) {
  const ImageDiffStats d = CompareImages(image, reference, &excluded);
  return {d.rmse, RmseOver(image, reference, edge), d.rmse_masked, d.rmse_lowfreq};
}

nlohmann::json ToJson(const Metrics& m) {
  return {{"rmse", m.rmse},
          {"rmse_edge", m.rmse_edge},
          {"rmse_masked", m.rmse_masked},
          {"rmse_lowfreq", m.rmse_lowfreq}};
}

SamplerKind Kind(const std::string& name) {
  const auto k = ParseSamplerKind(name);
  if (!k) throw std::runtime_error("unknown sampler '" + name + "' (sobol, independent)");
  return *k;
}

int Run(const Args& a) {
  const Image reference = ReadExr(a.reference);
  const SceneRuntime scene(LoadScene(a.scene));
  // Traces scene.accel itself: the camera (world coordinates) moves into the scene's frame
  // (scene_frame.h).
  CameraSpec spec = scene.description.cameras.empty() ? DefaultCamera(scene.description)
                                                      : scene.description.cameras.front();
  spec.width = reference.width();
  spec.height = reference.height();
  const Camera camera(spec, scene.description.origin);
  const std::vector<float> coverage = EmitterCoverage(scene.accel, camera);
  std::vector<uint8_t> edge(coverage.size());
  for (size_t i = 0; i < coverage.size(); ++i) edge[i] = coverage[i] > 0.0f && coverage[i] < 1.0f;
  const std::vector<uint8_t> excluded = EmitterExclusionMask(coverage, spec.width, spec.height);
  std::vector<uint32_t> pixels(size_t(spec.width) * spec.height);
  std::iota(pixels.begin(), pixels.end(), 0u);
  auto image_of = [&](const std::vector<Rgb>& sums, uint32_t spp) {
    Image img(spec.width, spec.height);
    for (size_t i = 0; i < sums.size(); ++i) img[i] = sums[i] * (1.0f / float(spp));
    return img;
  };
  const nlohmann::json common = {
      {"scene", a.scene},
      {"edge_pixels", std::count(edge.begin(), edge.end(), uint8_t(1))},
      {"excluded_pixels", std::count(excluded.begin(), excluded.end(), uint8_t(1))}};

  if (!a.photon_sampler.empty()) {
    JobRenderSettings settings;
    settings.integrator = IntegratorKind::kPhotonMap;
    settings.photons = a.photons;
    settings.sampler = Kind(a.photon_sampler);  // photon emission and scattering
    if (a.standalone) settings.direct = DirectLightMode::kNone;
    settings = settings.Resolved(scene.description);
    for (uint32_t m = 0; m < a.maps; ++m) {
      PhotonMapsOptions mo = settings.MapsOptions();
      mo.tracing.map_seed = MapSeed(a.seed, m);
      mo.tracing.threads = a.threads;
      const PhotonMaps maps = PhotonMaps::Build(scene.accel, scene.lights, mo);
      const PhotonMapIntegrator integrator(scene.accel, &scene.lights, maps,
                                           settings.IntegratorOptions(scene.accel.bounds()));
      std::vector<Rgb> sums(pixels.size());
      const auto t0 = std::chrono::steady_clock::now();
      RenderPixels(integrator, camera, pixels, 0, a.spp, PixelSeed(a.seed, m), a.threads, sums, nullptr,
                   nullptr, SamplerKind::kSobol);
      nlohmann::json j = common;
      j.update({{"mode", "photon-emission"},
                {"photon_sampler", a.photon_sampler},
                {"photons", a.photons},
                {"spp", a.spp},
                {"map", m},
                {"direct", a.standalone ? "photon-map" : "auto"},
                {"seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()}});
      j.update(ToJson(Measure(image_of(sums, a.spp), reference, edge, excluded)));
      std::printf("%s\n", j.dump().c_str());
      std::fflush(stdout);
    }
    return 0;
  }

  if (a.integrator != "path") throw std::runtime_error("progressive mode renders --integrator path only");
  const PathTracer tracer(scene.accel, scene.lights);
  const SamplerKind kind = Kind(a.sampler);
  std::vector<Rgb> sums(pixels.size());
  double seconds = 0;
  for (uint32_t begin = 0, end = 1; end <= a.max_spp; begin = end, end *= 2) {
    const RenderStats st =
        RenderPixels(tracer, camera, pixels, begin, end, a.seed, a.threads, sums, nullptr, nullptr, kind);
    seconds += st.seconds;
    nlohmann::json j = common;
    j.update({{"mode", "progressive"}, {"sampler", a.sampler}, {"spp", end}, {"seconds", seconds}});
    j.update(ToJson(Measure(image_of(sums, end), reference, edge, excluded)));
    std::printf("%s\n", j.dump().c_str());
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  pf::Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--scene")
      a.scene = v;
    else if (k == "--reference")
      a.reference = v;
    else if (k == "--sampler")
      a.sampler = v;
    else if (k == "--photon-sampler")
      a.photon_sampler = v;
    else if (k == "--integrator")
      a.integrator = v;
    else if (k == "--max-spp")
      a.max_spp = uint32_t(std::stoul(v));
    else if (k == "--spp")
      a.spp = uint32_t(std::stoul(v));
    else if (k == "--maps")
      a.maps = uint32_t(std::stoul(v));
    else if (k == "--photons")
      a.photons = std::stoull(v);
    else if (k == "--seed")
      a.seed = std::stoull(v);
    else if (k == "--threads")
      a.threads = std::stoi(v);
    else if (k == "--standalone")
      a.standalone = v == "1";
    else {
      std::fprintf(stderr,
                   "unknown option %s (see the comment at the top of sampler_convergence_bench.cpp)\n",
                   k.c_str());
      return 2;
    }
  }
  if (a.scene.empty() || a.reference.empty()) {
    std::fprintf(stderr, "usage: %s --scene S --reference R.exr [--sampler sobol|independent] ...\n",
                 argv[0]);
    return 2;
  }
  spdlog::set_level(spdlog::level::warn);
  try {
    return pf::Run(a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
