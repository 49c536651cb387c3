// The outlier test of result verification (server/scheduling/result_verification.h; docs/farm.md
// "Result verification") on real renders: how often it flags an honest result (false positives:
// each costs one extra render of the task, never a conviction) and how often it flags a result
// scaled by 1.5, 1000 or 0 (or by 1.1, 1.25 and 0.5, below what it promises to catch).
//
// Every task of a job is rendered with ExecuteTask, as a worker would, and scored in task order
// as the coordinator scores a merge: against the means of the earlier results of its group (up to
// kOutlierReferences), once kOutlierMinReferences exist. Several scenes, plans and seeds.
//
// Usage: result_verification_bench [--quick] [--json out.json] [--threads N]
#include <spdlog/spdlog.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench_stats.h"
#include "common/plan/task_executor.h"
#include "common/plan/task_plan.h"
#include "common/render/job_render_settings.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"
#include "server/scheduling/result_verification.h"

namespace {
namespace fs = std::filesystem;
using namespace pf;

struct Config {
  std::string name;
  std::string scene;  // folder/file under scenes/
  PlanSpec plan;
  int res = 32;
  uint64_t photons = 2000;
  int k = 20;
};

struct Tally {
  uint64_t results = 0, tested = 0, honest_flagged = 0;
  double honest_max_z = 0;
  std::vector<double> honest_z;
  std::map<std::string, uint64_t> flagged;  // by factor
};

const std::vector<std::pair<std::string, double>> kFactors = {{"x1.5", 1.5}, {"x1000", 1000}, {"x0", 0},
                                                              {"x1.1", 1.1}, {"x1.25", 1.25}, {"x0.5", 0.5}};

std::string g_statistic = "midmean";
double g_threshold = server::kOutlierThreshold;
double Statistic(const server::ResultSummary& s) {
  return g_statistic == "mean" ? s.mean : g_statistic == "midmean" ? s.midmean : s.median;
}

void RunJob(const Config& c, const SceneRuntime& scene, const CameraSpec& base_camera, uint64_t seed,
            int threads, Tally* t) {
  CameraSpec camera = base_camera;
  camera.width = camera.height = c.res;
  JobRenderSettings settings;
  settings.photons = c.photons;
  settings.k = c.k;
  const std::vector<TaskSpec> tasks = ExpandPlan(c.plan, camera.width, camera.height, seed);
  PhotonMapCache cache(4);
  std::map<uint64_t, std::vector<double>> groups;
  for (const TaskSpec& task : tasks) {
    const TaskOutput out = ExecuteTask(scene, c.scene, camera, settings, task, threads, &cache);
    const server::ResultSummary s = server::SummarizeResult(task, out.rgb_sums);
    const double value = Statistic(s);
    std::vector<double>& refs = groups[s.group];
    ++t->results;
    const server::OutlierScore honest = server::ScoreAgainst(value, refs, g_threshold);
    if (honest.tested) {
      ++t->tested;
      t->honest_z.push_back(honest.z);
      t->honest_max_z = std::max(t->honest_max_z, honest.z);
      t->honest_flagged += honest.outlier;
      for (const auto& [name, factor] : kFactors)
        t->flagged[name] += server::ScoreAgainst(value * factor, refs, g_threshold).outlier;
    }
    if (refs.size() >= server::kOutlierReferences) refs.erase(refs.begin());
    refs.push_back(value);
  }
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false;
  std::string json_path;
  int threads = 2;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
    if (!std::strcmp(argv[i], "--threads") && i + 1 < argc) threads = std::atoi(argv[++i]);
    if (!std::strcmp(argv[i], "--statistic") && i + 1 < argc) g_statistic = argv[++i];
    if (!std::strcmp(argv[i], "--threshold") && i + 1 < argc) g_threshold = std::atof(argv[++i]);
  }
  spdlog::set_level(spdlog::level::warn);
  const fs::path scenes = fs::path(PF_SOURCE_DIR) / "scenes";
  const uint32_t rounds = quick ? 8 : 32;
  std::vector<Config> configs;
  for (const char* s : {"cornell-box/cornell-box.json", "scene8/scene8.json", "office3/office3.json"}) {
    configs.push_back(
        {"skipping S=2, 32x32, 2000 photons, k 20 (the e2e job)", s,
         PlanSpec{.kind = PlanKind::kSkipping, .samples_per_pixel = 1, .stride = 2, .rounds = rounds}, 32,
         2000, 20});
    configs.push_back(
        {"skipping S=4, 64x64, 20000 photons, k 50", s,
         PlanSpec{.kind = PlanKind::kSkipping, .samples_per_pixel = 1, .stride = 4, .rounds = rounds / 2}, 64,
         20000, 50});
    configs.push_back({"multiple maps: 16 maps, 16x16 tiles, 64x64, 2 spp, 20000 photons, k 50", s,
                       PlanSpec{.kind = PlanKind::kMultipleMaps,
                                .maps = quick ? 8u : 16u,
                                .samples_per_pixel = 2,
                                .tile_size = 16},
                       64, 20000, 50});
  }
  const int seeds = quick ? 1 : 3;
  nlohmann::json out = {{"threshold", server::kOutlierThreshold},
                        {"relative_floor", server::kOutlierRelativeFloor},
                        {"references", server::kOutlierReferences},
                        {"min_references", server::kOutlierMinReferences},
                        {"configs", nlohmann::json::array()}};
  std::printf(
      "outlier test: z > %.1f (relative floor %.2f), against up to %zu earlier results of the group\n\n",
      server::kOutlierThreshold, server::kOutlierRelativeFloor, server::kOutlierReferences);
  std::printf("%-14s %-72s %7s %7s %9s %9s", "scene", "job", "tested", "honest+", "max z", "median z");
  for (const auto& [name, f] : kFactors) std::printf(" %7s", name.c_str());
  std::printf("\n");
  std::map<std::string, std::shared_ptr<SceneRuntime>> loaded;
  Tally total;
  for (const Config& c : configs) {
    auto& runtime = loaded[c.scene];
    if (!runtime) runtime = std::make_shared<SceneRuntime>(LoadScene(scenes / c.scene));
    const CameraSpec camera = runtime->description.cameras.empty() ? DefaultCamera(runtime->description)
                                                                   : runtime->description.cameras[0];
    Tally t;
    for (int s = 1; s <= seeds; ++s) RunJob(c, *runtime, camera, uint64_t(s), threads, &t);
    const std::string scene = fs::path(c.scene).parent_path().string();
    std::printf("%-14s %-72s %7llu %7llu %9.2f %9.2f", scene.c_str(), c.name.c_str(),
                (unsigned long long)t.tested, (unsigned long long)t.honest_flagged, t.honest_max_z,
                bench::Median(t.honest_z));
    nlohmann::json flagged;
    for (const auto& [name, f] : kFactors) {
      const double rate = t.tested ? double(t.flagged[name]) / double(t.tested) : 0.0;
      std::printf(" %6.1f%%", 100 * rate);
      flagged[name] = t.flagged[name];
      total.flagged[name] += t.flagged[name];
    }
    std::printf("\n");
    total.tested += t.tested;
    total.honest_flagged += t.honest_flagged;
    total.honest_max_z = std::max(total.honest_max_z, t.honest_max_z);
    out["configs"].push_back({{"scene", scene},
                              {"job", c.name},
                              {"seeds", seeds},
                              {"results", t.results},
                              {"tested", t.tested},
                              {"honest_flagged", t.honest_flagged},
                              {"honest_max_z", t.honest_max_z},
                              {"honest_median_z", bench::Median(t.honest_z)},
                              {"flagged", flagged}});
  }
  std::printf("\nall: %llu honest results tested, %llu flagged (false positives), max z %.2f;",
              (unsigned long long)total.tested, (unsigned long long)total.honest_flagged, total.honest_max_z);
  for (const auto& [name, f] : kFactors)
    std::printf(" %s %.1f%%", name.c_str(),
                total.tested ? 100.0 * double(total.flagged[name]) / double(total.tested) : 0.0);
  std::printf("\n");
  out["total"] = {{"tested", total.tested},
                  {"honest_flagged", total.honest_flagged},
                  {"honest_max_z", total.honest_max_z},
                  {"flagged", total.flagged}};
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(2) << "\n";
  return 0;
}
