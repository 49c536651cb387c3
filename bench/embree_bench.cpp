// Embree throughput on real scenes: rays/s per thread for camera rays,
// incoherent secondary rays (cosine-distributed from the camera hits) and shadow rays, and the
// path tracer's samples/s. Single thread, median of --repeats runs, printed as a table and JSON.
//
//   build/bench/embree_bench [--repeats 5] [--json out.json] [--res 256] [--clock wall|cpu]
//
// The secondary rays are bench/raw_rays.h's (photon_tracing_bench measures the same set), drawn
// from their own random stream since 2026-11-26 (docs/results/kernel.md §4, Run 3): the secondary
// and shadow ray sets differ from earlier runs' (the same distribution, other rays).
//
// --clock cpu times the ray loops by the process's CPU time (they run on one thread): on a shared,
// loaded machine the wall clock also counts the time spent waiting for a core.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <vector>

#include "bench/bench_scenes.h"
#include "bench/bench_stats.h"
#include "bench/raw_rays.h"
#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/core/rng.h"
#include "common/lights/light_sampler.h"
#include "common/render/path_tracer.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

using bench::Median;
using bench::TimeIt;

bool g_cpu_clock = false;  // --clock cpu

template <typename F>
double Time(F&& f) {
  return g_cpu_clock ? bench::CpuTimeIt(f) : TimeIt(f);
}

struct SceneResult {
  std::string scene;
  size_t triangles = 0;
  double build_seconds = 0, camera_rays_per_s = 0, secondary_rays_per_s = 0, shadow_rays_per_s = 0,
         path_samples_per_s = 0, path_rays_per_s = 0;
};

SceneResult BenchScene(const std::string& name, const std::string& path, int res, int repeats) {
  SceneResult r;
  r.scene = name;
  const SceneDescription scene = LoadScene(path);
  r.triangles = scene.NumTriangles();
  CameraSpec spec = scene.cameras.empty() ? DefaultCamera(scene) : scene.cameras.front();
  spec.width = spec.height = res;
  const Camera camera(spec, scene.origin);
  std::vector<double> build;
  for (int i = 0; i < repeats; ++i) build.push_back(TimeIt([&] { EmbreeScene s(scene); }));
  r.build_seconds = Median(build);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);

  // Fixed ray sets, generated once, so every repetition traces the same rays.
  std::vector<Ray> camera_rays, secondary, shadow;
  Rng rng(42, 1);
  for (int y = 0; y < res; ++y)
    for (int x = 0; x < res; ++x)
      camera_rays.push_back(camera.GenerateRay(x, y, rng.Uniform(), rng.Uniform()));
  // The incoherent secondary rays (bench/raw_rays.h, which photon_tracing_bench measures too).
  {
    Rng secondary_rng(42, 2);
    secondary = bench::IncoherentSecondaryRays(accel, camera, res, secondary_rng);
  }
  for (const Ray& cr : camera_rays) {
    const auto hit = accel.Intersect(cr);
    if (!hit) continue;
    if (!lights.empty()) {
      const LightSample ls = lights.Sample(rng.Uniform(), rng.Uniform(), rng.Uniform());
      const Vec3 o = accel.SpawnOrigin(*hit, ls.position - hit->position);
      const Vec3 to = ls.position - o;
      const float dist = Length(to);
      shadow.push_back(Ray{o, to / dist, dist * (1 - 1e-4f)});
    }
  }
  auto rate = [&](const std::vector<Ray>& rays, bool occl) {
    std::vector<double> t;
    volatile size_t sink = 0;
    for (int i = 0; i < repeats; ++i)
      t.push_back(Time([&] {
        size_t hits = 0;
        if (occl)
          for (const Ray& ray : rays) hits += accel.Occluded(ray);
        else
          hits = bench::IntersectAll(accel, rays);
        sink = sink + hits;
      }));
    return rays.size() / Median(t);
  };
  r.camera_rays_per_s = rate(camera_rays, false);
  r.secondary_rays_per_s = rate(secondary, false);
  r.shadow_rays_per_s = shadow.empty() ? 0 : rate(shadow, true);

  const PathTracer tracer(accel, lights);
  CameraSpec small = spec;
  small.width = small.height = std::max(16, res / 2);
  std::vector<double> ps, pr;
  for (int i = 0; i < repeats; ++i) {
    RenderStats st;
    RenderImage(tracer, Camera(small, scene.origin),
                RenderOptions{.spp = 4, .seed = uint64_t(i + 1), .threads = 1}, &st);
    ps.push_back(st.samples / st.seconds);
    pr.push_back((st.counters.rays + st.counters.shadow_rays) / st.seconds);
  }
  r.path_samples_per_s = Median(ps);
  r.path_rays_per_s = Median(pr);
  return r;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  int repeats = 5, res = 256;
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeats" && i + 1 < argc)
      repeats = std::max(1, std::atoi(argv[++i]));
    else if (a == "--json" && i + 1 < argc)
      json_path = argv[++i];
    else if (a == "--clock" && i + 1 < argc &&
             (std::string(argv[i + 1]) == "cpu" || std::string(argv[i + 1]) == "wall"))
      pf::g_cpu_clock = std::string(argv[++i]) == "cpu";
    else if (a == "--res" && i + 1 < argc)
      res = std::max(16, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "usage: %s [--repeats N] [--res R] [--clock wall|cpu] [--json out.json]\n",
                   argv[0]);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  const auto scenes = pf::bench::SceneManifests({"cornell-box", "office3"});
  nlohmann::json out = nlohmann::json::array();
  std::printf("Embree 3, one thread, median of %d runs, %dx%d camera rays, ray loops on the %s clock\n",
              repeats, res, res, pf::g_cpu_clock ? "cpu" : "wall");
  std::printf("%-12s %9s %9s %12s %12s %12s %12s %12s\n", "scene", "tris", "build ms", "camera Mr/s",
              "second. Mr/s", "shadow Mr/s", "path Ks/s", "path Mr/s");
  for (const auto& [name, path] : scenes) {
    const pf::SceneResult r = pf::BenchScene(name, path, res, repeats);
    std::printf("%-12s %9zu %9.1f %12.2f %12.2f %12.2f %12.1f %12.2f\n", r.scene.c_str(), r.triangles,
                r.build_seconds * 1e3, r.camera_rays_per_s * 1e-6, r.secondary_rays_per_s * 1e-6,
                r.shadow_rays_per_s * 1e-6, r.path_samples_per_s * 1e-3, r.path_rays_per_s * 1e-6);
    out.push_back({{"scene", r.scene},
                   {"triangles", r.triangles},
                   {"build_seconds", r.build_seconds},
                   {"camera_rays_per_s", r.camera_rays_per_s},
                   {"secondary_rays_per_s", r.secondary_rays_per_s},
                   {"shadow_rays_per_s", r.shadow_rays_per_s},
                   {"path_samples_per_s", r.path_samples_per_s},
                   {"path_rays_per_s", r.path_rays_per_s},
                   {"threads", 1},
                   {"clock", pf::g_cpu_clock ? "cpu" : "wall"},
                   {"repeats", repeats}});
  }
  const std::string text = out.dump(2);
  if (!json_path.empty()) std::ofstream(json_path) << text << "\n";
  std::printf("%s\n", text.c_str());
  return 0;
}
