// The range query of progressive photon mapping (PhotonMap::QueryRadius; Knaus & Zwicker 2011)
// against the k-NN query (PhotonMap::Query) at equal photon count: per scene one map of N photons,
// query points at the photons of a second map (where the renderer queries: on surfaces). The radius
// is the progressive plan's derived first radius (render/progressive_radius.h, the disk that holds
// about k photons of an evenly lit bounding box); the k-NN query then asks for the mean number the
// radius query found, so both return about as many photons. Repeats interleaved (k-NN, radius,
// k-NN, ...), medians, one thread.
//
//   build/bench/radius_query_bench [--photons 200000] [--k 50] [--queries 20000] [--repeats 5]
//                                  [--clock wall|cpu] [--json out.json]
#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "bench/bench_stats.h"
#include "common/photon/photon_maps.h"
#include "common/render/progressive_radius.h"
#include "common/scene/scene_loader.h"

using namespace pf;

int main(int argc, char** argv) {
  uint64_t photons = 200000;
  int k = 50, queries = 20000, repeats = 5;
  bool cpu_clock = false;
  std::string json_path;
  const std::map<std::string, std::function<void(const std::string&)>> flags = {
      {"--photons", [&](const std::string& v) { photons = std::stoull(v); }},
      {"--k", [&](const std::string& v) { k = std::stoi(v); }},
      {"--queries", [&](const std::string& v) { queries = std::max(1, std::stoi(v)); }},
      {"--repeats", [&](const std::string& v) { repeats = std::max(1, std::stoi(v)); }},
      {"--clock", [&](const std::string& v) { cpu_clock = v == "cpu"; }},
      {"--json", [&](const std::string& v) { json_path = v; }}};
  for (int i = 1; i < argc; i += 2) {
    const auto flag = flags.find(argv[i]);
    if (flag == flags.end() || i + 1 >= argc) {
      std::fprintf(stderr,
                   "usage: %s [--photons N] [--k K] [--queries Q] [--repeats N] [--clock wall|cpu] "
                   "[--json out.json]\n",
                   argv[0]);
      return 2;
    }
    flag->second(argv[i + 1]);
  }
  spdlog::set_level(spdlog::level::warn);
  const auto scenes = pf::bench::SceneManifests({"cornell-box", "office3"});
  const std::vector<std::pair<std::string, PhotonMapKind>> structures = {
      {"kdtree", PhotonMapKind::kKdTree},
      {"grid", PhotonMapKind::kGrid},
      {"bucket", PhotonMapKind::kBucketKdTree}};
  double load[3] = {0, 0, 0};
  getloadavg(load, 3);
  std::printf(
      "radius query vs k-NN: %llu photons, %d queries, radius for ~%d photons, 1 thread, %s s per query "
      "(median of %d, load %.1f)\n",
      (unsigned long long)photons, queries, k, cpu_clock ? "CPU" : "wall", repeats, load[0]);
  std::printf("%-12s %-8s %9s %9s %12s %12s %8s\n", "scene", "map", "radius", "found", "k-NN us", "radius us",
              "ratio");
  nlohmann::json out = nlohmann::json::array();
  for (const auto& [name, path] : scenes) {
    const SceneDescription scene = LoadScene(path);
    const EmbreeScene accel(scene);
    const LightSampler lights(accel);
    const float radius = float(DerivedInitialRadius(accel.bounds(), photons, k));
    PhotonMapsOptions points_options;
    points_options.tracing.photons = photons;
    points_options.tracing.map_seed = 2;
    const PhotonMaps points = PhotonMaps::Build(accel, lights, points_options);
    std::vector<Vec3> xs;
    for (size_t i = 0; i < points.global->size() && int(xs.size()) < queries; ++i)
      xs.push_back(points.global->photon(i * 7919 % points.global->size()).Position());
    for (const auto& [structure_name, structure] : structures) {
      PhotonMapsOptions mo;
      mo.tracing.photons = photons;
      mo.tracing.map_seed = 1;
      mo.kind = structure;
      const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
      const PhotonMap& map = *maps.global;
      NearestPhotons nearest;
      uint64_t found = 0;
      for (const Vec3& x : xs) {
        map.QueryRadius(x, radius, nearest);
        found += nearest.size();
      }
      const int equal_k = std::max(1, int(double(found) / double(xs.size()) + 0.5));
      std::vector<double> knn_s, radius_s;
      uint64_t sink = 0;
      auto time = [&](auto&& f) { return cpu_clock ? bench::CpuTimeIt(f) : bench::TimeIt(f); };
      for (int r = 0; r < repeats; ++r) {
        knn_s.push_back(time([&] {
          for (const Vec3& x : xs) {
            map.Query(x, equal_k, std::numeric_limits<float>::infinity(), nearest);
            sink += nearest.size();
          }
        }));
        radius_s.push_back(time([&] {
          for (const Vec3& x : xs) {
            map.QueryRadius(x, radius, nearest);
            sink += nearest.size();
          }
        }));
      }
      const double knn_us = 1e6 * bench::Median(knn_s) / double(xs.size());
      const double radius_us = 1e6 * bench::Median(radius_s) / double(xs.size());
      std::printf("%-12s %-8s %9.4f %9d %12.3f %12.3f %8.2f\n", name.c_str(), structure_name.c_str(), radius,
                  equal_k, knn_us, radius_us, radius_us / knn_us);
      out.push_back({{"scene", name},
                     {"map", structure_name},
                     {"photons", photons},
                     {"queries", xs.size()},
                     {"radius", radius},
                     {"mean_found", double(found) / double(xs.size())},
                     {"k", equal_k},
                     {"seconds_knn", knn_s},
                     {"seconds_radius", radius_s},
                     {"us_per_query_knn", knn_us},
                     {"us_per_query_radius", radius_us},
                     {"clock", cpu_clock ? "cpu" : "wall"},
                     {"load_average", load[0]},
                     {"sink", sink}});
    }
  }
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(1) << "\n";
  return 0;
}
