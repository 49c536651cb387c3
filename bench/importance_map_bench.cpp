// Where the photons of an importance-driven map land (Wald 1999, §4.7): builds the photon maps
// of a scene manifest's camera with importance off and on (the product's settings: `--direct mc`
// maps, i.e. the global map of indirect photons and the direct map) and counts the stored photons
// inside a box of the xz plane (the viewed room). Prints one JSON object per row and a table; the
// driver is bench/importance_rmse.py.
//
//   importance_map_bench --scene scenes/invisibledate/invisibledate.json --box 0,4,0,4
//       --photons 400000,2000000 [--threads 2] [--strength 4] [--min-probability 0.05]
#include <spdlog/spdlog.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "common/photon/photon_maps.h"
#include "common/plan/task_executor.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

std::vector<double> Numbers(const std::string& text) {
  std::vector<double> v;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) v.push_back(std::stod(item));
  return v;
}

int Run(int argc, char** argv) {
  std::string scene_path, box_text = "0,4,0,4", photons_text = "400000";
  int threads = 2;
  float strength = 4.0f, min_probability = 0.05f;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i], value = argv[i + 1];
    if (flag == "--scene")
      scene_path = value;
    else if (flag == "--box")
      box_text = value;
    else if (flag == "--photons")
      photons_text = value;
    else if (flag == "--threads")
      threads = std::stoi(value);
    else if (flag == "--strength")
      strength = std::stof(value);
    else if (flag == "--min-probability")
      min_probability = std::stof(value);
    else {
      std::fprintf(stderr, "unknown flag %s\n", flag.c_str());
      return 2;
    }
  }
  if (scene_path.empty()) {
    std::fprintf(stderr,
                 "usage: importance_map_bench --scene MANIFEST [--box x0,x1,z0,z1] [--photons N,...]\n");
    return 2;
  }
  spdlog::set_level(spdlog::level::warn);
  const SceneRuntime scene(LoadScene(scene_path));
  const Camera camera(scene.description.cameras.front(), scene.description.origin);
  const std::vector<double> box = Numbers(box_text);
  std::printf("%-10s %-10s %12s %12s %12s %10s %9s\n", "importance", "photons", "stored", "in box",
              "fraction", "rejected", "trace s");
  for (double photons : Numbers(photons_text))
    for (ImportanceMode mode : {ImportanceMode::kOff, ImportanceMode::kOn}) {
      JobRenderSettings s;
      s.photons = uint64_t(photons);
      s.direct = DirectLightMode::kMonteCarlo;
      s.importance = mode;
      s.importance_strength = strength;
      s.importance_min_probability = min_probability;
      s = s.Resolved(scene.description);
      PhotonMapsOptions mo = s.MapsOptions();
      mo.tracing.map_seed = 1;
      mo.tracing.threads = threads;
      const PhotonMaps maps = PhotonMaps::Build(scene.accel, scene.lights, mo, &camera);
      uint64_t stored = 0, inside = 0;
      for (const PhotonMap* map : {maps.global.get(), maps.direct.get(), maps.caustic.get()}) {
        if (!map) continue;
        for (const Photon& p : map->photons()) {
          const Vec3d x = Vec3d(p.Position()) + scene.description.origin;  // world (scene_frame.h)
          ++stored;
          inside += x.x >= box[0] && x.x <= box[1] && x.z >= box[2] && x.z <= box[3];
        }
      }
      const double fraction = stored ? double(inside) / double(stored) : 0.0;
      std::printf("%-10s %-10.0f %12llu %12llu %12.4f %10llu %9.2f\n", ImportanceModeName(mode), photons,
                  (unsigned long long)stored, (unsigned long long)inside, fraction,
                  (unsigned long long)maps.stats.rejected, maps.stats.trace_seconds);
      const nlohmann::json row = {{"importance", ImportanceModeName(mode)},
                                  {"photons", uint64_t(photons)},
                                  {"stored", stored},
                                  {"stored_in_box", inside},
                                  {"fraction_in_box", fraction},
                                  {"rejected", maps.stats.rejected},
                                  {"importons", maps.stats.importons},
                                  {"trace_seconds", maps.stats.trace_seconds}};
      std::printf("JSON %s\n", row.dump().c_str());
    }
  return 0;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  try {
    return pf::Run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "importance_map_bench: %s\n", e.what());
    return 1;
  }
}
