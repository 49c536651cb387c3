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
// Photons (default): REAL photons from the photon tracer (photon_tracer.h) in
// scenes/cornell-box and scenes/office3: for each N, enough photons are emitted (map seed 1,
// a pilot run measures stored/emitted) to store at least N, and N of the stored ones (direct,
// indirect and caustic photons together, i.e. a global map that keeps the direct photons, as
// in standalone rendering) are kept by even thinning. Query points: the hits of the
// manifest camera's primary rays, one jittered ray per pixel (Rng keyed by the pixel, so
// deterministic), the camera's resolution scaled so that its larger side is 256 pixels, in
// scan-line order (as a renderer queries). Rays that miss are dropped.
//
// --synthetic: the earlier stand-in (no tracer needed): photons on the surfaces of a
// Cornell-box-like room with a density falling off from the light plus 10% caustic blobs;
// queries uniform by area on the same surfaces.
//
// The machines are shared: the load average (/proc/loadavg) is printed before and after the
// run and stored in the JSON; tables show thread CPU time by default.
//
// Usage: photon_map_bench [--quick] [--synthetic] [--scenes cornell-box,office3] [--reps N]
//                         [--json out.json] [--wall] [--grid-sweep] [--cache DIR]
//                         [--profile STRUCT --scene S --n N --k K]
//   --quick: N up to 1M and fewer queries.
//   --wall: tables in wall-clock time instead of thread CPU time (both are in the JSON).
//   --grid-sweep: only measure grid query time against its photons-per-voxel target.
//   --cache DIR: keep traced photons and query points in DIR (raw 18-byte photons), so that
//     repeated runs (and valgrind runs) do not trace again. Same content as without it.
//   --profile STRUCT: build one structure (kd-cycle, kd-widest, kd-widest-plane, grid,
//     nanoflann) and run the query set once through pf_bench_profile_queries(), for
//     `valgrind --tool=callgrind --toggle-collect=pf_bench_profile_queries`; prints kd-tree
//     traversal statistics (nodes visited per query). Use with --cache.
//   --leaf L: photons per bucket of the bucketed kd-trees (default: BucketKdOptions' 32).
//   --hint-grow G: the hinted queries' hint = G × the previous query's k-th distance (1.2).

#include <spdlog/spdlog.h>
#include <nanoflann.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "bench/photon_workloads.h"
#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/core/math.h"
#include "common/core/rng.h"
#include "common/lights/light_sampler.h"
#include "common/photon/bucket_kdtree.h"
#include "common/photon/grid.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon.h"
#include "common/photon/photon_map.h"
#include "common/photon/photon_tracer.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

using namespace bench;  // the workloads (bench/photon_workloads.h)
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

std::string LoadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string a, b, c;
  in >> a >> b >> c;
  return a + " " + b + " " + c;
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
  bool synthetic = false;
  int reps = 3;
  std::string json_path;
  std::string cache_dir;
  std::vector<std::string> scenes = {"cornell-box", "office3"};
  int leaf_size = BucketKdOptions{}.leaf_size;  // --leaf: photons per bucket of the bucketed kd-trees
  std::vector<std::size_t> sizes;  // --sizes: photon counts (default 100k,1M,10M; --quick 100k,1M)
  // --profile
  std::string profile;
  std::size_t profile_n = 1000000;
  int profile_k = 50;
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

// Query points for one k: every `stride`-th camera hit (spread over the whole image).
std::vector<Vec3> Subset(const std::vector<Vec3>& points, std::size_t stride) {
  std::vector<Vec3> out;
  for (std::size_t i = 0; i < points.size(); i += stride) out.push_back(points[i]);
  return out;
}

// Runs the k-NN queries through one of our maps; the k-th distances go to `kth`.
Stopwatch::Lap QueryOurs(const PhotonMap& map, const std::vector<Vec3>& points, int k,
                         std::vector<float>& kth) {
  NearestPhotons heap;
  kth.resize(points.size());
  map.Query(points[0], k, std::numeric_limits<float>::infinity(), heap);  // warm the heap
  const Stopwatch watch;
  for (std::size_t i = 0; i < points.size(); ++i) {
    map.Query(points[i], k, std::numeric_limits<float>::infinity(), heap);
    kth[i] = heap.MaxDistanceSquared();
  }
  return watch.Elapsed();
}

// PhotonMap::QueryWithHint with the previous query's k-th distance × kHintGrow as the hint
// (the queries are camera hits in scan-line order: each one's predecessor is a neighbouring
// pixel, as for a renderer's thread walking its tile). Exact; misses re-query unbounded.
// (--hint-grow overrides it, to measure the trade-off: a smaller ball against more misses.)
constexpr float kHintGrow = 1.2f;
float g_hint_grow = kHintGrow;
Stopwatch::Lap QueryOursHinted(const PhotonMap& map, const std::vector<Vec3>& points, int k,
                               std::vector<float>& kth, std::size_t* misses = nullptr) {
  NearestPhotons heap;
  kth.resize(points.size());
  map.Query(points[0], k, std::numeric_limits<float>::infinity(), heap);  // warm the heap
  std::size_t missed = 0;
  float hint = 0.0f;
  const Stopwatch watch;
  for (std::size_t i = 0; i < points.size(); ++i) {
    missed += map.QueryWithHint(points[i], k, std::numeric_limits<float>::infinity(), hint, heap) ? 0 : 1;
    kth[i] = heap.MaxDistanceSquared();
    hint = g_hint_grow * std::sqrt(kth[i]);
  }
  const Stopwatch::Lap lap = watch.Elapsed();
  if (misses != nullptr) *misses = missed;
  return lap;
}

Stopwatch::Lap QueryNano(const NanoTree& tree, const std::vector<Vec3>& points, int k,
                         std::vector<float>& kth) {
  std::vector<uint32_t> idx(static_cast<std::size_t>(k));
  std::vector<float> d2(static_cast<std::size_t>(k));
  kth.resize(points.size());
  const Stopwatch watch;
  for (std::size_t i = 0; i < points.size(); ++i) {
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
  std::printf("Load average (1/5/15 min) at start: %s (shared machine, %u cores)\n", LoadAverage().c_str(),
              std::thread::hardware_concurrency());
  std::printf(
      "Same photons and same query points for every structure; k-NN with max_radius = inf.\n"
      "kd trees use the cell-distance culling test (KdCulling::kCellDistance) unless noted.\n\n");
}

// --grid-sweep: query time against the grid's photons-per-occupied-voxel target t, to check
// the default rule t = 2.2·sqrt(k) (grid.h).
int GridSweep(const Config& config, Workload& workload) {
  const std::size_t n = config.quick ? 100000 : 1000000;
  PrintHeader(config);
  TraceInfo info;
  const std::vector<Photon> photons = workload.Photons(n, &info);
  const std::vector<Vec3>& points = workload.Queries();
  std::printf("Grid sweep, %s, N=%s: us/query for t = c*sqrt(k) photons per occupied voxel\n",
              workload.name().c_str(), HumanCount(n).c_str());
  const double cs[] = {0.5, 1.0, 1.5, 2.2, 3.0, 4.5, 6.5};
  std::printf("%-5s", "k");
  for (double c : cs) std::printf(" c=%-8.1f", c);
  std::printf("\n");
  for (int k : {10, 50, 100, 500}) {
    const std::vector<Vec3> subset = Subset(points, k >= 500 ? 8 : 2);
    std::printf("%-5d", k);
    for (double c : cs) {
      GridOptions options;
      options.expected_k = k;
      options.photons_per_voxel = float(c * std::sqrt(double(k)));
      GridPhotonMap grid(options);
      grid.AddPhotons(photons);
      grid.PrepareForQuery();
      std::vector<float> kth;
      const Timing t = MedianTiming(config.reps, [&] { return QueryOurs(grid, subset, k, kth); });
      std::printf(" %-10.2f", 1e6 * (config.wall ? t.wall : t.cpu) / double(subset.size()));
      std::fflush(stdout);
    }
    std::printf("\n");
  }
  std::printf("Load average at end: %s\n", LoadAverage().c_str());
  return 0;
}

const char* const kNames[] = {"kd level%3",    "kd widest",  "kd widest/plane", "grid",
                              "bucket median", "bucket mid", "bucket mid+hint", "nanoflann"};
const char* const kProfileNames[] = {"kd-cycle",      "kd-widest",  "kd-widest-plane", "grid",
                                     "bucket-median", "bucket-mid", "bucket-mid-hint", "nanoflann"};
constexpr int kCols = 8, kBucketMedian = 4, kBucketMid = 5, kBucketHint = 6, kNano = 7;

// The bucketed kd-tree (bucket_kdtree.h) with the bench's leaf size (--leaf).
std::unique_ptr<PhotonMap> MakeBucketTree(BucketSplit split, int leaf_size) {
  BucketKdOptions options;
  options.split = split;
  options.leaf_size = leaf_size;
  return std::make_unique<BucketKdTree>(options);
}

}  // namespace
}  // namespace pf

// Outside the anonymous namespace with C linkage, so that callgrind can toggle on its name:
// valgrind --tool=callgrind --collect-atstart=no --toggle-collect=pf_bench_profile_queries ...
extern "C" __attribute__((noinline)) double pf_bench_profile_queries(const pf::PhotonMap* map,
                                                                     const pf::NanoTree* nano,
                                                                     const std::vector<pf::Vec3>* points,
                                                                     int k, bool hinted) {
  std::vector<float> kth;
  double sum = 0;
  if (map != nullptr && hinted) {
    pf::QueryOursHinted(*map, *points, k, kth);
  } else if (map != nullptr) {
    pf::QueryOurs(*map, *points, k, kth);
  } else {
    pf::QueryNano(*nano, *points, k, kth);
  }
  for (float d : kth) sum += d;
  return sum;
}

namespace pf {
namespace {

int Profile(const Config& config, Workload& workload) {
  int s = -1;
  for (int i = 0; i < kCols; ++i)
    if (config.profile == kProfileNames[i]) s = i;
  if (s < 0) {
    std::fprintf(stderr,
                 "--profile: one of kd-cycle, kd-widest, kd-widest-plane, grid, bucket-median, bucket-mid, "
                 "nanoflann\n");
    return 1;
  }
  TraceInfo info;
  const std::vector<Photon> photons = workload.Photons(config.profile_n, &info);
  const std::vector<Vec3>& points = workload.Queries();
  std::unique_ptr<PhotonMap> map;
  std::unique_ptr<NanoTree> nano;
  const PhotonCloud cloud{photons.data(), photons.size()};
  if (s == kNano) {
    nano = std::make_unique<NanoTree>(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  } else if (s == 3) {
    GridOptions options;
    options.expected_k = config.profile_k;
    map = std::make_unique<GridPhotonMap>(options);
  } else if (s == kBucketMedian || s == kBucketMid || s == kBucketHint) {
    map =
        MakeBucketTree(s == kBucketMedian ? BucketSplit::kMedian : BucketSplit::kMidpoint, config.leaf_size);
  } else {
    map = std::make_unique<KdTree>(s == 0 ? KdSplitRule::kLevelCycle : KdSplitRule::kWidestExtent,
                                   s == 2 ? KdCulling::kPlaneDistance : KdCulling::kCellDistance);
  }
  if (map) {
    map->AddPhotons(photons);
    const Stopwatch build;
    map->PrepareForQuery();
    const Stopwatch::Lap lap = build.Elapsed();
    std::printf("build: %.3f s cpu, %.3f s wall (%.3f s cpu per million photons)\n", lap.cpu, lap.wall,
                lap.cpu / (double(photons.size()) * 1e-6));
  }
  const Stopwatch watch;
  const double sum =
      pf_bench_profile_queries(map.get(), nano.get(), &points, config.profile_k, s == kBucketHint);
  const Stopwatch::Lap lap = watch.Elapsed();
  std::printf("%s %s N=%s k=%d: %zu queries, %.3f us/query cpu, %.3f wall (checksum %.6g)\n",
              workload.name().c_str(), kProfileNames[s], HumanCount(photons.size()).c_str(), config.profile_k,
              points.size(), 1e6 * lap.cpu / double(points.size()), 1e6 * lap.wall / double(points.size()),
              sum);
  if (const auto* bucket = dynamic_cast<const BucketKdTree*>(map.get()))
    std::printf("bucket tree: %zu nodes, %zu leaves, depth %d, leaf kernel %s, %.2f bytes/photon\n",
                bucket->node_count(), bucket->leaf_count(), bucket->depth(), bucket->simd(),
                double(bucket->MemoryBytes()) / double(photons.size()));
  if (const auto* kd = dynamic_cast<const KdTree*>(map.get())) {
    KdTree::SearchStats total;
    NearestPhotons heap;
    for (const Vec3& x : points) {
      KdTree::SearchStats stats;
      kd->QueryWithStats(x, config.profile_k, std::numeric_limits<float>::infinity(), heap, &stats);
      total.nodes += stats.nodes;
      total.inserts += stats.inserts;
      total.pushes += stats.pushes;
      total.pops += stats.pops;
    }
    const double q = double(points.size());
    std::printf(
        "per query: %.1f nodes visited, %.1f heap inserts, %.1f far children pushed, %.1f popped and "
        "visited\n",
        double(total.nodes) / q, double(total.inserts) / q, double(total.pushes) / q, double(total.pops) / q);
  }
  return 0;
}

int RunWorkload(const Config& config, Workload& workload, nlohmann::json& out) {
  std::vector<std::size_t> sizes = config.quick ? std::vector<std::size_t>{100000, 1000000}
                                                : std::vector<std::size_t>{100000, 1000000, 10000000};
  if (!config.sizes.empty()) sizes = config.sizes;
  const std::vector<int> ks = {10, 50, 100, 500};
  // Every stride-th camera hit: ~65k queries for k ≤ 50 (/4 with --quick).
  auto stride_for_k = [&](int k) -> std::size_t {
    const std::size_t base = k <= 50 ? 1 : k <= 100 ? 2 : 8;
    return config.quick ? base * 4 : base;
  };
  auto pick = [&](const Timing& t) { return config.wall ? t.wall : t.cpu; };

  const std::string load_before = LoadAverage();
  std::printf("=== %s ===\n%s\n", workload.name().c_str(), workload.description().c_str());
  out["name"] = workload.name();
  out["description"] = workload.description();
  out["loadavg_before"] = load_before;
  const std::vector<Vec3>& all_points = workload.Queries();
  std::printf("Query points: %zu", all_points.size());
  if (auto* scene = dynamic_cast<SceneWorkload*>(&workload))
    std::printf(" camera-ray hits of %d x %d pixels", scene->width(), scene->height());
  std::printf("\n");
  out["query_points"] = all_points.size();
  nlohmann::json& builds = out["build"];
  nlohmann::json& queries_json = out["query"];
  nlohmann::json& tracing_json = out["tracing"];

  struct BuildRow {
    std::size_t n;
    Timing t[kCols];
    double bytes[kCols];
    TraceInfo trace;
  };
  struct QueryRow {
    std::size_t n;
    int k;
    std::size_t count;
    Timing t[kCols];
    long mismatches;
    std::size_t hint_misses;  // queries of "bucket mid+hint" whose hint held < k photons
  };
  std::vector<BuildRow> build_rows;
  std::vector<QueryRow> query_rows;

  for (const std::size_t n : sizes) {
    std::fprintf(stderr, "[%s N=%s] photons...\n", workload.name().c_str(), HumanCount(n).c_str());
    BuildRow row{};
    row.n = n;
    const std::vector<Photon> photons = workload.Photons(n, &row.trace);
    tracing_json.push_back({{"n", n},
                            {"emitted", row.trace.emitted},
                            {"stored", row.trace.stored},
                            {"direct", row.trace.direct},
                            {"indirect", row.trace.indirect},
                            {"caustic", row.trace.caustic},
                            {"trace_wall_seconds_all_threads", row.trace.seconds},
                            {"from_cache", row.trace.cached}});

    // --- Build ----------------------------------------------------------------------------
    std::fprintf(stderr, "[%s N=%s] building...\n", workload.name().c_str(), HumanCount(n).c_str());
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
    std::unique_ptr<PhotonMap> kd_cycle, kd_widest, grid50, bucket_median, bucket_mid;
    row.t[0] = build_map(kd_cycle, [] { return std::make_unique<KdTree>(KdSplitRule::kLevelCycle); });
    row.t[1] = build_map(kd_widest, [] { return std::make_unique<KdTree>(KdSplitRule::kWidestExtent); });
    row.t[2] = row.t[1];  // same tree, other culling test
    GridOptions options50;
    options50.expected_k = 50;
    row.t[3] = build_map(grid50, [&] { return std::make_unique<GridPhotonMap>(options50); });
    row.t[kBucketMedian] =
        build_map(bucket_median, [&] { return MakeBucketTree(BucketSplit::kMedian, config.leaf_size); });
    row.t[kBucketMid] =
        build_map(bucket_mid, [&] { return MakeBucketTree(BucketSplit::kMidpoint, config.leaf_size); });
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
    widest_plane.AddPhotons(widest_tree->photons());  // already in tree order: same tree again
    widest_plane.PrepareForQuery();
    row.bytes[0] = double(kd_cycle->MemoryBytes()) / double(n);
    row.bytes[1] = row.bytes[2] = double(kd_widest->MemoryBytes()) / double(n);
    row.bytes[3] = double(grid50->MemoryBytes()) / double(n);
    row.bytes[kBucketMedian] = double(bucket_median->MemoryBytes()) / double(n);
    row.bytes[kBucketMid] = row.bytes[kBucketHint] = double(bucket_mid->MemoryBytes()) / double(n);
    row.t[kBucketHint] = row.t[kBucketMid];  // same tree, hinted queries
    // nanoflann reads our photon array (18 B/photon) plus its index permutation and nodes.
    row.bytes[kNano] = double(n * sizeof(Photon) + nano->usedMemory(*nano)) / double(n);
    build_rows.push_back(row);
    for (int s = 0; s < kCols; ++s) {
      if (s == 2 || s == kBucketHint) continue;
      builds.push_back({{"n", n},
                        {"structure", kNames[s]},
                        {"wall_seconds_median", row.t[s].wall},
                        {"cpu_seconds_median", row.t[s].cpu},
                        {"cpu_seconds_per_million", row.t[s].cpu / (double(n) * 1e-6)},
                        {"bytes_per_photon", row.bytes[s]}});
    }
    builds.back()["grid_resolution_k50"] = static_cast<const GridPhotonMap*>(grid50.get())->resolution();
    grid50.reset();

    // --- Queries --------------------------------------------------------------------------
    for (const int k : ks) {
      const std::vector<Vec3> points = Subset(all_points, stride_for_k(k));
      const std::size_t count = points.size();
      std::fprintf(stderr, "[%s N=%s] k=%d: %zu queries x %d reps...\n", workload.name().c_str(),
                   HumanCount(n).c_str(), k, count, config.reps);
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
        laps[0].push_back(QueryOurs(*kd_cycle, points, k, kth[0]));
        laps[1].push_back(QueryOurs(*kd_widest, points, k, kth[1]));
        laps[2].push_back(QueryOurs(widest_plane, points, k, kth[2]));
        laps[3].push_back(QueryOurs(grid, points, k, kth[3]));
        laps[kBucketMedian].push_back(QueryOurs(*bucket_median, points, k, kth[kBucketMedian]));
        laps[kBucketMid].push_back(QueryOurs(*bucket_mid, points, k, kth[kBucketMid]));
        laps[kBucketHint].push_back(
            QueryOursHinted(*bucket_mid, points, k, kth[kBucketHint], &q.hint_misses));
        laps[kNano].push_back(QueryNano(*nano, points, k, kth[kNano]));
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
                                {"structure", kNames[s]},
                                {"queries", count},
                                {"wall_us_per_query", 1e6 * q.t[s].wall / double(count)},
                                {"cpu_us_per_query", 1e6 * q.t[s].cpu / double(count)},
                                {"queries_per_second", double(count) / pick(q.t[s])},
                                {"speedup_vs_nanoflann", pick(q.t[kNano]) / pick(q.t[s])}});
      }
      queries_json.back()["kth_distance_mismatches"] = q.mismatches;
      queries_json.back()["hint_misses"] = q.hint_misses;
      queries_json.back()["grid_resolution"] = grid.resolution();
      queries_json.back()["grid_photons_per_occupied_voxel"] = grid.photons_per_occupied_voxel();
    }
  }
  const std::string load_after = LoadAverage();
  out["loadavg_after"] = load_after;

  // --- Tables ----------------------------------------------------------------------------
  std::printf("Photons (map seed %llu): emitted -> stored -> kept\n",
              (unsigned long long)SceneWorkload::kMapSeed);
  for (const BuildRow& r : build_rows) {
    if (r.trace.stored == 0) continue;
    std::printf("  N=%-5s emitted %llu, stored %llu (direct %llu, indirect %llu, caustic %llu)%s\n",
                HumanCount(r.n).c_str(), (unsigned long long)r.trace.emitted,
                (unsigned long long)r.trace.stored, (unsigned long long)r.trace.direct,
                (unsigned long long)r.trace.indirect, (unsigned long long)r.trace.caustic,
                r.trace.cached ? " [from cache]" : "");
  }
  std::printf("\nBuild time [s], 1 thread (in parentheses: time / nanoflann's)\n");
  std::printf("%-6s %-16s %-16s %-16s %-16s %-16s %-10s | %-9s | thesis BuildTree (1999 hardware)\n", "N",
              "kd level%3", "kd widest", "grid (k=50)", "bucket median", "bucket mid", "nanoflann",
              "widest s/M");
  for (const BuildRow& r : build_rows) {
    std::printf("%-6s", HumanCount(r.n).c_str());
    for (int s : {0, 1, 3, kBucketMedian, kBucketMid}) {
      char cell[64];
      std::snprintf(cell, sizeof cell, "%.3f (%.2fx)", pick(r.t[s]), pick(r.t[s]) / pick(r.t[kNano]));
      std::printf(" %-16s", cell);
    }
    std::printf(" %-10.3f | %-9.3f | %s\n", pick(r.t[kNano]), pick(r.t[1]) / (double(r.n) * 1e-6),
                ThesisBuildTree(r.n).c_str());
  }
  std::printf(
      "\nMemory [bytes/photon] (maps: photons + structure; nanoflann: our photon array + its index)\n");
  std::printf("%-6s %-11s %-11s %-11s %-13s %-11s %-11s\n", "N", "kd level%3", "kd widest", "grid (k=50)",
              "bucket median", "bucket mid", "nanoflann");
  for (const BuildRow& r : build_rows) {
    std::printf("%-6s", HumanCount(r.n).c_str());
    for (int s : {0, 1, 3}) std::printf(" %-11.2f", r.bytes[s]);
    std::printf(" %-13.2f %-11.2f %-11.2f", r.bytes[kBucketMedian], r.bytes[kBucketMid], r.bytes[kNano]);
    std::printf("\n");
  }
  std::printf("\nk-NN queries, 1 thread: us/query (x = speed-up over nanoflann, >1 is faster)\n");
  std::printf("%-6s %-4s %-6s", "N", "k", "#q");
  for (int s = 0; s < kCols; ++s) std::printf(" %-16s", kNames[s]);
  std::printf(" mismatches hint-misses\n");
  for (const QueryRow& r : query_rows) {
    std::printf("%-6s %-4d %-6zu", HumanCount(r.n).c_str(), r.k, r.count);
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
    std::printf(" %-10ld %zu\n", r.mismatches, r.hint_misses);
  }
  std::printf(
      "(mismatches: queries whose k-th neighbour distance differs from nanoflann's; must be 0.\n"
      " bucket mid+hint: the bucket mid tree queried with QueryWithHint, hint = %.1f x the previous\n"
      " query's k-th distance; hint-misses: queries re-run unbounded because the hint held < k;\n"
      " bucket trees: leaf size %d)\n",
      double(g_hint_grow), config.leaf_size);
  std::printf("Load average (1/5/15 min): before %s, after %s\n\n", load_before.c_str(), load_after.c_str());
  long bad = 0;
  for (const QueryRow& r : query_rows) bad += r.mismatches;
  return bad == 0 ? 0 : 2;
}

int Run(const Config& config) {
  std::vector<std::unique_ptr<Workload>> workloads;
  if (config.synthetic) {
    workloads.push_back(std::make_unique<SyntheticWorkload>());
  } else {
    for (const std::string& s : config.scenes)
      workloads.push_back(std::make_unique<SceneWorkload>(
          s, std::filesystem::path(PF_SOURCE_DIR) / "scenes" / s / (s + ".json"), config.cache_dir));
  }
  if (!config.profile.empty()) return Profile(config, *workloads.front());
  if (config.grid_sweep) return GridSweep(config, *workloads.front());

  PrintHeader(config);
  nlohmann::json out;
  out["cpu"] = CpuName();
  out["repetitions"] = config.reps;
  out["table_clock"] = config.wall ? "wall" : "thread_cpu";
  out["nanoflann"] =
      "1.4.3, KDTreeSingleIndexAdaptor, leaf_max_size 10, L2_Simple_Adaptor<float>, uint32 indices";
  out["grid_rule"] = "photons_per_voxel = 2.2*sqrt(expected_k); queries use a grid built with expected_k = k";
  out["loadavg_start"] = LoadAverage();
  out["bucket_leaf_size"] = config.leaf_size;
  out["hint_grow"] = g_hint_grow;
  int status = 0;
  for (auto& w : workloads) {
    nlohmann::json& section = out["workloads"].emplace_back();
    status = std::max(status, RunWorkload(config, *w, section));
    std::fflush(stdout);
  }
  out["loadavg_end"] = LoadAverage();
  if (!config.json_path.empty()) {
    std::ofstream f(config.json_path);
    f << out.dump(2) << "\n";
    std::printf("JSON written to %s\n", config.json_path.c_str());
  }
  return status;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::warn);
  pf::Config config;
  auto usage = [&] {
    std::fprintf(stderr,
                 "usage: %s [--quick] [--synthetic] [--scenes a,b] [--reps N] [--json out.json] [--wall]\n"
                 "          [--grid-sweep] [--cache DIR] [--profile STRUCT [--n N] [--k K]] [--leaf L]\n"
                 "          [--sizes 100000,1000000] [--hint-grow 1.2]\n",
                 argv[0]);
    return 1;
  };
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "--quick") {
      config.quick = true;
    } else if (arg == "--synthetic") {
      config.synthetic = true;
    } else if (arg == "--scenes" && has_value) {
      config.scenes.clear();
      std::stringstream list(argv[++i]);
      for (std::string s; std::getline(list, s, ',');)
        if (!s.empty()) config.scenes.push_back(s);
      if (config.scenes.empty()) return usage();
    } else if (arg == "--json" && has_value) {
      config.json_path = argv[++i];
    } else if (arg == "--cache" && has_value) {
      config.cache_dir = argv[++i];
    } else if (arg == "--wall") {
      config.wall = true;
    } else if (arg == "--grid-sweep") {
      config.grid_sweep = true;
    } else if (arg == "--reps" && has_value) {
      config.reps = std::max(1, std::atoi(argv[++i]));
    } else if (arg == "--profile" && has_value) {
      config.profile = argv[++i];
    } else if (arg == "--n" && has_value) {
      config.profile_n = std::size_t(std::atoll(argv[++i]));
    } else if (arg == "--leaf" && has_value) {
      config.leaf_size = std::clamp(std::atoi(argv[++i]), 1, 64);
    } else if (arg == "--sizes" && has_value) {
      std::stringstream list(argv[++i]);
      for (std::string v; std::getline(list, v, ',');)
        if (!v.empty()) config.sizes.push_back(std::size_t(std::atoll(v.c_str())));
    } else if (arg == "--hint-grow" && has_value) {
      pf::g_hint_grow = std::clamp(float(std::atof(argv[++i])), 1.0f, 4.0f);
    } else if (arg == "--k" && has_value) {
      config.profile_k = std::max(1, std::atoi(argv[++i]));
    } else {
      return usage();
    }
  }
  return pf::Run(config);
}
