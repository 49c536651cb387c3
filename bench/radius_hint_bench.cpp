// The pixel radius hint of the photon-map integrator (PhotonMapIntegratorOptions::pixel_radius_hint):
// render time with and without it, side by side in one run. Each sample's estimates search the
// ball of the previous sample's k-th distance × 1.2 first (PhotonMap::QueryWithHint). One photon
// map per scene and structure, the same for both rows; process CPU time of RenderImage on one
// thread, repeats interleaved (hint off, on, off, on, ...), medians. Also checks that the images
// agree (the same photons are found; only the summation order may differ: max relative
// difference printed).
//
//   build/bench/radius_hint_bench [--photons 200000] [--k 50] [--spp 4] [--res 128] [--repeats 5]
//                                 [--direct none|mc] [--json out.json]
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "bench/bench_stats.h"
#include "common/photon/photon_maps.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"

using namespace pf;

int main(int argc, char** argv) {
  uint64_t photons = 200000;
  int k = 50, res = 128, repeats = 5;
  uint32_t spp = 4;
  std::string direct = "none", json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--photons")
      photons = std::stoull(next());
    else if (a == "--k")
      k = std::stoi(next());
    else if (a == "--spp")
      spp = uint32_t(std::stoul(next()));
    else if (a == "--res")
      res = std::stoi(next());
    else if (a == "--repeats")
      repeats = std::max(1, std::stoi(next()));
    else if (a == "--direct")
      direct = next();
    else if (a == "--json")
      json_path = next();
    else {
      std::fprintf(stderr,
                   "usage: %s [--photons N] [--k K] [--spp S] [--res R] [--repeats N] [--direct none|mc] "
                   "[--json out.json]\n",
                   argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  const auto scenes = pf::bench::SceneManifests({"cornell-box", "office3"});
  const std::vector<std::pair<std::string, PhotonMapKind>> structures = {
      {"kdtree", PhotonMapKind::kKdTree}, {"bucket", PhotonMapKind::kBucketKdTree}};
  double load[3] = {0, 0, 0};
  getloadavg(load, 3);
  std::printf(
      "radius hint: %llu photons, k %d, %u spp, %dx%d, direct %s, 1 thread, process CPU s, median of %d "
      "(load %.1f)\n",
      (unsigned long long)photons, k, spp, res, res, direct.c_str(), repeats, load[0]);
  std::printf("%-12s %-8s %10s %10s %8s %14s\n", "scene", "map", "no hint s", "hint s", "speed-up",
              "max rel diff");
  nlohmann::json out = nlohmann::json::array();
  for (const auto& [name, path] : scenes) {
    const SceneDescription scene = LoadScene(path);
    const EmbreeScene accel(scene);
    const LightSampler lights(accel);
    CameraSpec spec = scene.cameras.empty() ? DefaultCamera(scene) : scene.cameras.front();
    spec.width = spec.height = res;
    const Camera camera(spec);
    for (const auto& [structure_name, structure] : structures) {
      PhotonMapIntegratorOptions io;
      io.global.k = k;
      io.caustic = DefaultCausticOptions(k, accel.bounds());
      io.direct = direct == "mc" ? DirectLightMode::kMonteCarlo : DirectLightMode::kNone;
      io.direct_photons = DefaultDirectPhotonOptions(io.global, accel.bounds());
      PhotonMapsOptions mo;
      mo.tracing.photons = photons;
      mo.tracing.map_seed = 1;
      mo.kind = structure;
      ConfigureMapsFor(io, &mo);
      const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
      std::vector<double> seconds[2];
      Image images[2];
      for (int r = 0; r < repeats; ++r) {
        for (int hint = 0; hint < 2; ++hint) {
          PhotonMapIntegratorOptions o = io;
          o.pixel_radius_hint = hint == 1;
          const PhotonMapIntegrator integrator(accel, &lights, maps, o);
          seconds[hint].push_back(bench::CpuTimeIt([&] {
            images[hint] =
                RenderImage(integrator, camera, RenderOptions{.spp = spp, .seed = 3, .threads = 1});
          }));
        }
      }
      double max_rel = 0;
      for (size_t i = 0; i < images[0].size(); ++i) {
        const double a = images[0][i].Mean(), b = images[1][i].Mean();
        if (a > 0) max_rel = std::max(max_rel, std::abs(a - b) / a);
      }
      const double off = bench::Median(seconds[0]), on = bench::Median(seconds[1]);
      std::printf("%-12s %-8s %10.3f %10.3f %8.2f %14.2e\n", name.c_str(), structure_name.c_str(), off, on,
                  off / on, max_rel);
      out.push_back({{"scene", name},
                     {"map", structure_name},
                     {"photons", photons},
                     {"k", k},
                     {"spp", spp},
                     {"res", res},
                     {"direct", direct},
                     {"seconds_no_hint", seconds[0]},
                     {"seconds_hint", seconds[1]},
                     {"median_no_hint", off},
                     {"median_hint", on},
                     {"speedup", off / on},
                     {"max_relative_difference", max_rel},
                     {"load_average", load[0]}});
    }
  }
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(1) << "\n";
  return 0;
}
