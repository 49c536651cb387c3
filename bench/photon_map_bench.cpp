// Photon map benchmark (Wald 1999, §2.3 kd-tree and §2.4 grid) against nanoflann.
//
// One run, side by side on the SAME photons and the SAME query points:
//   * build time for N = 100k, 1M, 10M: kd-tree (level % 3), kd-tree (widest extent), grid,
//     nanoflann KDTreeSingleIndexAdaptor (leaf size 10, its default) — next to the thesis's
//     Table 2.1;
//   * single-thread k-NN queries per second for k ∈ {10, 50, 100, 500} (plus the widest
//     kd-tree with the thesis's plane-distance culling test, for comparison);
//   * memory in bytes per photon.
// Medians of --reps repetitions (default 3); ratios are relative to nanoflann.
//
// Photons: there is no photon tracer yet, so photons are generated on the surfaces of a
// Cornell-box-like room (6 walls, 2 rotated boxes) with a density that falls off away from
// the ceiling light, plus 10% in caustic-like gaussian blobs on the floor. Query points
// (stand-ins for camera-ray hits) are uniform by area over the same surfaces, 10% of them in
// the caustic blobs.
//
// Usage: photon_map_bench [--quick] [--reps N] [--json out.json] [--wall] [--grid-sweep]
//   --quick: N up to 1M and fewer queries.
//   --wall: tables in wall-clock time instead of thread CPU time (both are in the JSON).
//   --grid-sweep: only measure grid query time against its photons-per-voxel target.

#include <nanoflann.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "common/core/math.h"
#include "common/core/rng.h"
#include "common/photon/grid.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon.h"
#include "common/photon/photon_map.h"

namespace pf {
namespace {

using Clock = std::chrono::steady_clock;

// Both clocks are read around every measurement: wall time (std::chrono::steady_clock) and
// this thread's CPU time. The machines these run on are shared (other builds compete for
// the 2 cores), so the tables show CPU time by default, which excludes time spent
// descheduled; --wall shows wall time. The JSON has both.
struct Stopwatch {
  Clock::time_point wall0 = Clock::now();
  double cpu0 = ThreadCpuSeconds();
  static double ThreadCpuSeconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
  }
  struct Lap {
    double wall, cpu;
  };
  Lap Elapsed() const {
    return {std::chrono::duration<double>(Clock::now() - wall0).count(), ThreadCpuSeconds() - cpu0};
  }
};

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 == 1 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// ---------------------------------------------------------------------------------------
// The stand-in scene: a Cornell-box-like room, 5.5 units on a side, y up.

struct Quad {  // the parallelogram origin + s·u + t·v, s, t ∈ [0, 1]
  Vec3 origin, u, v;
  float Area() const { return Length(Cross(u, v)); }
  Vec3 Point(float s, float t) const { return origin + u * s + v * t; }
};

std::vector<Quad> RoomQuads() {
  const float w = 5.5f;
  std::vector<Quad> quads = {
      {{0, 0, 0}, {w, 0, 0}, {0, 0, w}},  // floor
      {{0, w, 0}, {w, 0, 0}, {0, 0, w}},  // ceiling
      {{0, 0, w}, {w, 0, 0}, {0, w, 0}},  // back
      {{0, 0, 0}, {w, 0, 0}, {0, w, 0}},  // front
      {{0, 0, 0}, {0, 0, w}, {0, w, 0}},  // left
      {{w, 0, 0}, {0, 0, w}, {0, w, 0}},  // right
  };
  // Two boxes rotated about y, like the classic short and tall blocks: 4 sides + top each.
  auto add_box = [&quads](Vec3 centre, float half, float height, float angle) {
    const Vec3 a(std::cos(angle) * half, 0, std::sin(angle) * half);
    const Vec3 b(-std::sin(angle) * half, 0, std::cos(angle) * half);
    const Vec3 corners[4] = {centre - a - b, centre + a - b, centre + a + b, centre - a + b};
    for (int i = 0; i < 4; ++i)
      quads.push_back({corners[i], corners[(i + 1) % 4] - corners[i], {0, height, 0}});
    quads.push_back({corners[0] + Vec3(0, height, 0), a * 2.0f, b * 2.0f});
  };
  add_box({1.85f, 0, 1.7f}, 0.83f, 1.65f, -0.29f);
  add_box({3.7f, 0, 3.5f}, 0.83f, 3.3f, 0.3f);
  return quads;
}

class SurfaceSampler {
 public:
  explicit SurfaceSampler(std::vector<Quad> quads) : quads_(std::move(quads)) {
    float total = 0;
    for (const Quad& q : quads_) cdf_.push_back(total += q.Area());
    for (float& c : cdf_) c /= total;
  }
  Vec3 Uniform(Rng& rng) const {
    const float r = rng.Uniform();
    const std::size_t i = std::min<std::size_t>(std::lower_bound(cdf_.begin(), cdf_.end(), r) - cdf_.begin(),
                                                quads_.size() - 1);
    return quads_[i].Point(rng.Uniform(), rng.Uniform());
  }

 private:
  std::vector<Quad> quads_;
  std::vector<float> cdf_;
};

const Vec3 kLight(2.75f, 5.45f, 2.75f);
// Caustic-like blobs on the floor (e.g. under a glass sphere): centre and sigma.
const std::pair<Vec3, float> kCaustics[] = {
    {{3.0f, 0.0f, 1.2f}, 0.03f}, {{1.0f, 0.0f, 3.6f}, 0.06f}, {{4.6f, 0.0f, 1.0f}, 0.12f}};

float Gauss(Rng& rng) {
  const float u = std::max(rng.Uniform(), 1e-7f), v = rng.Uniform();
  return std::sqrt(-2.0f * std::log(u)) * std::cos(kTwoPi * v);
}

Vec3 CausticPoint(Rng& rng) {
  const auto& [centre, sigma] = kCaustics[rng.UniformInt(3)];
  const float x = std::clamp(centre.x + sigma * Gauss(rng), 0.0f, 5.5f);
  const float z = std::clamp(centre.z + sigma * Gauss(rng), 0.0f, 5.5f);
  return {x, 0.0f, z};
}

std::vector<Photon> MakePhotons(std::size_t n, uint64_t seed) {
  const SurfaceSampler surfaces(RoomQuads());
  Rng rng = Rng::ForKey(HashKey(seed, 1));
  std::vector<Photon> photons;
  photons.reserve(n);
  while (photons.size() < n) {
    Vec3 p;
    if (rng.Uniform() < 0.1f) {
      p = CausticPoint(rng);
    } else {
      // Density falls off with the distance to the light (rejection sampling).
      p = surfaces.Uniform(rng);
      const float d2 = LengthSquared(p - kLight);
      if (rng.Uniform() > 1.0f / (1.0f + d2 / 9.0f)) continue;
    }
    const float phi = kTwoPi * rng.Uniform(), cos_t = std::sqrt(rng.Uniform());
    const float sin_t = std::sqrt(1.0f - cos_t * cos_t);
    const Vec3 dir(sin_t * std::cos(phi), -cos_t, sin_t * std::sin(phi));
    photons.push_back(Photon::Make(p, dir, Rgb(1e-6f, 0.8e-6f, 0.6e-6f) * (0.5f + rng.Uniform())));
  }
  return photons;
}

std::vector<Vec3> MakeQueries(std::size_t n, uint64_t seed) {
  const SurfaceSampler surfaces(RoomQuads());
  Rng rng = Rng::ForKey(HashKey(seed, 2));
  std::vector<Vec3> q;
  q.reserve(n);
  for (std::size_t i = 0; i < n; ++i)
    q.push_back(rng.Uniform() < 0.1f ? CausticPoint(rng) : surfaces.Uniform(rng));
  return q;
}

// ---------------------------------------------------------------------------------------
// nanoflann over the same 18-byte photon array (it keeps its own index permutation).

struct PhotonCloud {
  const Photon* photons = nullptr;
  std::size_t n = 0;
  std::size_t kdtree_get_point_count() const { return n; }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const { return photons[i].position[dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const {
    return false;
  }
};
using NanoTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PhotonCloud>,
                                                     PhotonCloud, 3, uint32_t>;

// ---------------------------------------------------------------------------------------

struct Config {
  bool quick = false;
  bool wall = false;
  bool grid_sweep = false;
  int reps = 3;
  std::string json_path;
};

std::string HumanCount(std::size_t n) {
  if (n >= 1000000 && n % 1000000 == 0) return std::to_string(n / 1000000) + "M";
  if (n >= 1000 && n % 1000 == 0) return std::to_string(n / 1000) + "k";
  return std::to_string(n);
}

std::string CpuName() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown";
}

// Thesis, Table 2.1 (DEC Alpha 333, SCENE6): BuildTree seconds; 10M from the text (§2.3,
// "about 3 minutes on one MIPS R10000/250MHz").
std::string ThesisBuildTree(std::size_t n) {
  if (n == 100000) return "7 s (Table 2.1)";
  if (n == 1000000) return "~70 s (extrap. from 700k: 48 s)";
  if (n == 10000000) return "~180 s (R10000, §2.3 text)";
  return "-";
}

struct Timing {
  double wall = 0, cpu = 0;  // medians, seconds
};

// Median over repetitions of (wall, cpu) seconds of `fn`, which returns its own Lap (so that
// untimed setup can stay outside).
template <typename Fn>
Timing MedianTiming(int reps, Fn fn) {
  std::vector<double> wall, cpu;
  for (int r = 0; r < reps; ++r) {
    const Stopwatch::Lap lap = fn();
    wall.push_back(lap.wall);
    cpu.push_back(lap.cpu);
  }
  return {Median(wall), Median(cpu)};
}

// Runs `count` k-NN queries through one of our maps; the k-th distances go to `kth`.
Stopwatch::Lap QueryOurs(const PhotonMap& map, const std::vector<Vec3>& points, std::size_t count, int k,
                         std::vector<float>& kth) {
  NearestPhotons heap;
  kth.resize(count);
  map.Query(points[0], k, std::numeric_limits<float>::infinity(), heap);  // warm the heap
  const Stopwatch watch;
  for (std::size_t i = 0; i < count; ++i) {
    map.Query(points[i], k, std::numeric_limits<float>::infinity(), heap);
    kth[i] = heap.MaxDistanceSquared();
  }
  return watch.Elapsed();
}

Stopwatch::Lap QueryNano(const NanoTree& tree, const std::vector<Vec3>& points, std::size_t count, int k,
                         std::vector<float>& kth) {
  std::vector<uint32_t> idx(static_cast<std::size_t>(k));
  std::vector<float> d2(static_cast<std::size_t>(k));
  kth.resize(count);
  const Stopwatch watch;
  for (std::size_t i = 0; i < count; ++i) {
    const float x[3] = {points[i].x, points[i].y, points[i].z};
    const std::size_t found = tree.knnSearch(x, std::size_t(k), idx.data(), d2.data());
    kth[i] = found > 0 ? d2[found - 1] : 0.0f;
  }
  return watch.Elapsed();
}

void PrintHeader(const Config& config) {
  std::printf(
      "photonfarm photon map benchmark (Wald 1999, §2.3 kd-tree / §2.4 grid) vs nanoflann 1.4.3\n"
      "(Debian libnanoflann-dev; its header says 0x142)\n");
  std::printf("CPU: %s, single thread, medians of %d repetitions, %s time\n", CpuName().c_str(), config.reps,
              config.wall ? "wall-clock" : "thread CPU");
  std::printf(
      "Photons: SYNTHETIC (no photon tracer yet), on the surfaces of a Cornell-box-like room\n"
      "(6 walls + 2 rotated boxes, density falling off from the ceiling light) + 10%% in\n"
      "caustic-like gaussian blobs on the floor. Query points (stand-ins for camera-ray hits):\n"
      "uniform by area on the same surfaces, 10%% in the caustic blobs. Same photons and same\n"
      "query points for every structure; k-NN with max_radius = inf.\n"
      "kd trees use the cell-distance culling test (KdCulling::kCellDistance) unless noted.\n\n");
}

// --grid-sweep: query time against the grid's photons-per-occupied-voxel target t, to check
// the default rule t = 2.2·sqrt(k) (grid.h).
int GridSweep(const Config& config) {
  const std::size_t n = config.quick ? 100000 : 1000000;
  PrintHeader(config);
  const std::vector<Photon> photons = MakePhotons(n, 1999);
  const std::vector<Vec3> points = MakeQueries(100000, 2024);
  std::printf("Grid sweep, N=%s: us/query for t = c*sqrt(k) photons per occupied voxel\n",
              HumanCount(n).c_str());
  const double cs[] = {0.5, 1.0, 1.5, 2.2, 3.0, 4.5, 6.5};
  std::printf("%-5s", "k");
  for (double c : cs) std::printf(" c=%-8.1f", c);
  std::printf("\n");
  for (int k : {10, 50, 100, 500}) {
    const std::size_t count = k >= 500 ? 5000 : 30000;
    std::printf("%-5d", k);
    for (double c : cs) {
      GridOptions options;
      options.expected_k = k;
      options.photons_per_voxel = float(c * std::sqrt(double(k)));
      GridPhotonMap grid(options);
      grid.AddPhotons(photons);
      grid.PrepareForQuery();
      std::vector<float> kth;
      const Timing t = MedianTiming(config.reps, [&] { return QueryOurs(grid, points, count, k, kth); });
      std::printf(" %-10.2f", 1e6 * (config.wall ? t.wall : t.cpu) / double(count));
      std::fflush(stdout);
    }
    std::printf("\n");
  }
  return 0;
}

int Run(const Config& config) {
  if (config.grid_sweep) return GridSweep(config);
  const std::vector<std::size_t> sizes = config.quick ? std::vector<std::size_t>{100000, 1000000}
                                                      : std::vector<std::size_t>{100000, 1000000, 10000000};
  const std::vector<int> ks = {10, 50, 100, 500};
  auto queries_for_k = [&](int k) -> std::size_t {
    const std::size_t base = k <= 10 ? 100000 : k <= 50 ? 50000 : k <= 100 ? 30000 : 6000;
    return config.quick ? base / 4 : base;
  };
  auto pick = [&](const Timing& t) { return config.wall ? t.wall : t.cpu; };

  PrintHeader(config);
  nlohmann::json out;
  out["cpu"] = CpuName();
  out["repetitions"] = config.reps;
  out["table_clock"] = config.wall ? "wall" : "thread_cpu";
  out["photons"] =
      "synthetic: Cornell-box-like room surfaces (density falling off from the light) + 10% caustic blobs";
  out["queries"] =
      "uniform by area on the room surfaces, 10% in the caustic blobs (stand-ins for camera hits)";
  out["nanoflann"] =
      "1.4.3, KDTreeSingleIndexAdaptor, leaf_max_size 10, L2_Simple_Adaptor<float>, uint32 indices";
  out["grid_rule"] = "photons_per_voxel = 2.2*sqrt(expected_k); queries use a grid built with expected_k = k";
  nlohmann::json& builds = out["build"];
  nlohmann::json& queries_json = out["query"];

  // Columns of the tables. The kd-tree with the thesis's plane-distance culling is queried too.
  const char* names[] = {"kd level%3", "kd widest", "kd widest/plane", "grid", "nanoflann"};
  constexpr int kCols = 5, kNano = 4;
  struct BuildRow {
    std::size_t n;
    Timing t[kCols];
    double bytes[kCols];
  };
  struct QueryRow {
    std::size_t n;
    int k;
    std::size_t count;
    Timing t[kCols];
    long mismatches;
  };
  std::vector<BuildRow> build_rows;
  std::vector<QueryRow> query_rows;

  for (const std::size_t n : sizes) {
    std::fprintf(stderr, "[N=%s] generating photons...\n", HumanCount(n).c_str());
    const std::vector<Photon> photons = MakePhotons(n, 1999);
    const std::vector<Vec3> points = MakeQueries(100000, 2024);

    // --- Build ----------------------------------------------------------------------------
    std::fprintf(stderr, "[N=%s] building...\n", HumanCount(n).c_str());
    BuildRow row{};
    row.n = n;
    auto build_map = [&](std::unique_ptr<PhotonMap>& holder, auto factory) {
      return MedianTiming(config.reps, [&] {
        holder.reset();
        holder = factory();
        holder->AddPhotons(photons);  // copying the photons in is not part of the build
        const Stopwatch watch;
        holder->PrepareForQuery();
        return watch.Elapsed();
      });
    };
    std::unique_ptr<PhotonMap> kd_cycle, kd_widest, grid50;
    row.t[0] = build_map(kd_cycle, [] { return std::make_unique<KdTree>(KdSplitRule::kLevelCycle); });
    row.t[1] = build_map(kd_widest, [] { return std::make_unique<KdTree>(KdSplitRule::kWidestExtent); });
    row.t[2] = row.t[1];  // same tree, other culling test
    GridOptions options50;
    options50.expected_k = 50;
    row.t[3] = build_map(grid50, [&] { return std::make_unique<GridPhotonMap>(options50); });
    const PhotonCloud cloud{photons.data(), photons.size()};
    std::unique_ptr<NanoTree> nano;
    row.t[kNano] = MedianTiming(config.reps, [&] {
      nano.reset();
      const Stopwatch watch;
      nano = std::make_unique<NanoTree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
      return watch.Elapsed();
    });
    const KdTree* widest_tree = static_cast<const KdTree*>(kd_widest.get());
    KdTree widest_plane(KdSplitRule::kWidestExtent, KdCulling::kPlaneDistance);
    widest_plane.AddPhotons(widest_tree->photons());  // already in tree order: rebuild is a no-op reshuffle
    widest_plane.PrepareForQuery();
    row.bytes[0] = double(kd_cycle->MemoryBytes()) / double(n);
    row.bytes[1] = row.bytes[2] = double(kd_widest->MemoryBytes()) / double(n);
    row.bytes[3] = double(grid50->MemoryBytes()) / double(n);
    // nanoflann reads our photon array (18 B/photon) plus its index permutation and nodes.
    row.bytes[kNano] = double(n * sizeof(Photon) + nano->usedMemory(*nano)) / double(n);
    build_rows.push_back(row);
    for (int s = 0; s < kCols; ++s) {
      if (s == 2) continue;
      builds.push_back({{"n", n},
                        {"structure", names[s]},
                        {"wall_seconds_median", row.t[s].wall},
                        {"cpu_seconds_median", row.t[s].cpu},
                        {"bytes_per_photon", row.bytes[s]}});
    }
    builds.back()["grid_resolution_k50"] = static_cast<const GridPhotonMap*>(grid50.get())->resolution();
    grid50.reset();

    // --- Queries --------------------------------------------------------------------------
    for (const int k : ks) {
      const std::size_t count = queries_for_k(k);
      std::fprintf(stderr, "[N=%s] k=%d: %zu queries x %d reps...\n", HumanCount(n).c_str(), k, count,
                   config.reps);
      // The grid is built for the k it is queried with (its resolution depends on k, §2.4).
      GridOptions grid_options;
      grid_options.expected_k = k;
      GridPhotonMap grid(grid_options);
      grid.AddPhotons(photons);
      grid.PrepareForQuery();

      QueryRow q{};
      q.n = n;
      q.k = k;
      q.count = count;
      std::vector<float> kth[kCols];
      std::vector<Stopwatch::Lap> laps[kCols];
      for (int r = 0; r < config.reps; ++r) {  // interleaved, so that load changes hit all alike
        laps[0].push_back(QueryOurs(*kd_cycle, points, count, k, kth[0]));
        laps[1].push_back(QueryOurs(*kd_widest, points, count, k, kth[1]));
        laps[2].push_back(QueryOurs(widest_plane, points, count, k, kth[2]));
        laps[3].push_back(QueryOurs(grid, points, count, k, kth[3]));
        laps[kNano].push_back(QueryNano(*nano, points, count, k, kth[kNano]));
      }
      for (int s = 0; s < kCols; ++s) {
        std::vector<double> wall, cpu;
        for (const auto& lap : laps[s]) {
          wall.push_back(lap.wall);
          cpu.push_back(lap.cpu);
        }
        q.t[s] = {Median(wall), Median(cpu)};
      }
      // Every structure must find the same k-th neighbour distance, bit for bit.
      for (std::size_t i = 0; i < count; ++i)
        for (int s = 0; s < kNano; ++s) q.mismatches += kth[s][i] != kth[kNano][i] ? 1 : 0;
      query_rows.push_back(q);
      for (int s = 0; s < kCols; ++s) {
        queries_json.push_back({{"n", n},
                                {"k", k},
                                {"structure", names[s]},
                                {"queries", count},
                                {"wall_us_per_query", 1e6 * q.t[s].wall / double(count)},
                                {"cpu_us_per_query", 1e6 * q.t[s].cpu / double(count)},
                                {"queries_per_second", double(count) / pick(q.t[s])},
                                {"speedup_vs_nanoflann", pick(q.t[kNano]) / pick(q.t[s])}});
      }
      queries_json.back()["kth_distance_mismatches"] = q.mismatches;
      queries_json.back()["grid_resolution"] = grid.resolution();
      queries_json.back()["grid_photons_per_occupied_voxel"] = grid.photons_per_occupied_voxel();
    }
  }

  // --- Tables ----------------------------------------------------------------------------
  std::printf("Build time [s] (in parentheses: time / nanoflann's)\n");
  std::printf("%-6s %-16s %-16s %-16s %-10s | thesis BuildTree (1999 hardware)\n", "N", "kd level%3",
              "kd widest", "grid (k=50)", "nanoflann");
  for (const BuildRow& r : build_rows) {
    std::printf("%-6s", HumanCount(r.n).c_str());
    for (int s : {0, 1, 3}) {
      char cell[64];
      std::snprintf(cell, sizeof cell, "%.3f (%.2fx)", pick(r.t[s]), pick(r.t[s]) / pick(r.t[kNano]));
      std::printf(" %-16s", cell);
    }
    std::printf(" %-10.3f | %s\n", pick(r.t[kNano]), ThesisBuildTree(r.n).c_str());
  }
  std::printf(
      "\nMemory [bytes/photon] (maps: photons + structure; nanoflann: our photon array + its index)\n");
  std::printf("%-6s %-11s %-11s %-11s %-11s\n", "N", "kd level%3", "kd widest", "grid (k=50)", "nanoflann");
  for (const BuildRow& r : build_rows) {
    std::printf("%-6s", HumanCount(r.n).c_str());
    for (int s : {0, 1, 3, kNano}) std::printf(" %-11.2f", r.bytes[s]);
    std::printf("\n");
  }
  std::printf("\nk-NN queries, 1 thread: us/query (x = speed-up over nanoflann, >1 is faster)\n");
  std::printf("%-6s %-4s", "N", "k");
  for (int s = 0; s < kCols; ++s) std::printf(" %-16s", names[s]);
  std::printf(" mismatches\n");
  for (const QueryRow& r : query_rows) {
    std::printf("%-6s %-4d", HumanCount(r.n).c_str(), r.k);
    for (int s = 0; s < kCols; ++s) {
      char cell[64];
      const double us = 1e6 * pick(r.t[s]) / double(r.count);
      if (s == kNano) {
        std::snprintf(cell, sizeof cell, "%.2f", us);
      } else {
        std::snprintf(cell, sizeof cell, "%.2f (%.2fx)", us, pick(r.t[kNano]) / pick(r.t[s]));
      }
      std::printf(" %-16s", cell);
    }
    std::printf(" %ld\n", r.mismatches);
  }
  std::printf("(mismatches: queries whose k-th neighbour distance differs from nanoflann's; must be 0)\n");

  if (!config.json_path.empty()) {
    std::ofstream f(config.json_path);
    f << out.dump(2) << "\n";
    std::printf("\nJSON written to %s\n", config.json_path.c_str());
  }
  long bad = 0;
  for (const QueryRow& r : query_rows) bad += r.mismatches;
  return bad == 0 ? 0 : 2;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  pf::Config config;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--quick") {
      config.quick = true;
    } else if (arg == "--json" && i + 1 < argc) {
      config.json_path = argv[++i];
    } else if (arg == "--wall") {
      config.wall = true;
    } else if (arg == "--grid-sweep") {
      config.grid_sweep = true;
    } else if (arg == "--reps" && i + 1 < argc) {
      config.reps = std::max(1, std::atoi(argv[++i]));
    } else {
      std::fprintf(stderr, "usage: %s [--quick] [--reps N] [--json out.json] [--wall] [--grid-sweep]\n",
                   argv[0]);
      return 1;
    }
  }
  return pf::Run(config);
}
