// The hierarchical plan (Wald 1999, §4.5; common/plan/hierarchical.h) with a synthetic renderer:
// f_j(p) = g(p) + error of map j at p, for analytic g and errors whose statistics are known, so
// the reconstruction and its variance can be compared with exact values.
#include "common/plan/hierarchical.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <set>

#include "common/core/error.h"
#include "common/core/rng.h"
#include "common/plan/accumulator.h"
#include "common/render/progressive_radius.h"

namespace pf {
namespace {

constexpr double kPi = 3.14159265358979323846;

PlanSpec Plan(uint32_t levels, uint32_t dims, uint32_t n0, uint32_t nmin, double decay = 2) {
  return PlanSpec{.kind = PlanKind::kHierarchical,
                  .levels = levels,
                  .dims = dims,
                  .base_samples = n0,
                  .min_samples = nmin,
                  .decay = decay};
}

// Value of pixel (x, y) under map `map` in trial `trial` (one sample).
using Render = std::function<double(uint32_t x, uint32_t y, uint64_t map, uint64_t trial)>;

double Gaussian(uint64_t key) {
  Rng rng = Rng::ForKey(key);
  const double u1 = std::max(rng.UniformDouble(), 1e-300), u2 = rng.UniformDouble();
  return std::sqrt(-2 * std::log(u1)) * std::cos(2 * kPi * u2);
}

std::vector<float> RenderTask(const TaskSpec& t, const std::vector<uint32_t>& pixels, int width,
                              const Render& f, uint64_t trial) {
  std::vector<float> sums(pixels.size() * 3);
  for (size_t i = 0; i < pixels.size(); ++i) {
    const double v =
        f(pixels[i] % width, pixels[i] / width, t.map_index, trial) * (t.sample_end - t.sample_begin);
    for (int c = 0; c < 3; ++c) sums[3 * i + c] = float(v);
  }
  return sums;
}

// Runs the whole plan (static tasks, then localization as the results imply) in the given order.
HierarchicalAssembly RunPlan(const PlanSpec& plan, int w, int h, const Render& f, uint64_t trial = 0,
                             bool reverse = false, std::vector<TaskSpec>* all = nullptr) {
  HierarchicalAssembly acc(plan, w, h);
  size_t done = 0;
  for (;;) {
    std::vector<TaskSpec> tasks = HierarchicalTasks(plan, w, h, 5, acc);
    if (tasks.size() == done) {
      if (all) *all = tasks;
      return acc;
    }
    std::vector<TaskSpec> batch(tasks.begin() + done, tasks.end());
    if (reverse) std::reverse(batch.begin(), batch.end());
    for (const TaskSpec& t : batch) {
      const std::vector<uint32_t> px = PixelsOf(t.pixels, w, h);
      acc.Add(t, px, RenderTask(t, px, w, f, trial), t.sample_end - t.sample_begin);
    }
    done = tasks.size();
  }
}

TEST(Hierarchy, OneDimensionalLevelsAreThoseOfTheThesis) {
  // A scanline of 2^4 + 1 pixels: level of x = 4 − (trailing zeros of x), parents x ± 2^(4−l).
  const Hierarchy h(17, 1, 4, 1);
  EXPECT_EQ(h.LevelOf(0), 0u);
  EXPECT_EQ(h.LevelOf(16), 0u);
  for (uint32_t x = 1; x < 16; ++x) {
    const uint32_t l = 4 - uint32_t(std::countr_zero(x));
    EXPECT_EQ(h.LevelOf(x), l) << x;
    const Hierarchy::Parents p = h.ParentsOf(x);
    ASSERT_EQ(p.count, 2u);
    EXPECT_EQ(p.pixel[0], x - (1u << (4 - l)));
    EXPECT_EQ(p.pixel[1], x + (1u << (4 - l)));
    EXPECT_EQ(p.weight[0], 0.5);
  }
  EXPECT_EQ(h.PointsOf(4, 0, 1).size(), 8u);
  EXPECT_EQ(h.TaskPixels(4, 0, 1).size(), 17u);  // the 8 new points and their 9 neighbours
}

TEST(Hierarchy, EveryPixelHasALevelAndParentsOfLowerLevelsForAnySize) {
  for (uint32_t dims : {1u, 2u}) {
    for (auto [w, h, L] : {std::tuple{17, 17, 4u}, {23, 9, 3u}, {5, 31, 5u}, {1, 1, 1u}, {40, 3, 2u}}) {
      const Hierarchy hier(w, h, L, dims);
      std::vector<uint64_t> per_level(L + 1, 0);
      for (uint32_t p = 0; p < uint32_t(w * h); ++p) {
        const uint32_t l = hier.LevelOf(p);
        ASSERT_LE(l, L);
        ++per_level[l];
        const Hierarchy::Parents par = hier.ParentsOf(p);
        EXPECT_EQ(par.count == 0, l == 0) << p;
        double wsum = 0;
        for (uint32_t k = 0; k < par.count; ++k) {
          EXPECT_LT(hier.LevelOf(par.pixel[k]), l);
          wsum += par.weight[k];
        }
        if (l > 0) {
          EXPECT_NEAR(wsum, 1.0, 1e-12);
        }
      }
      uint64_t total = 0;
      for (uint32_t l = 0; l <= L; ++l) {
        EXPECT_EQ(hier.PointsOf(l, 0, h).size(), per_level[l]);
        total += per_level[l];
      }
      EXPECT_EQ(total, uint64_t(w) * h);
    }
  }
}

TEST(Hierarchy, ScheduleFallsWithTheLevelAndEachSampleHasItsOwnMap) {
  const PlanSpec plan = Plan(4, 1, 16, 2);
  const HierarchySchedule s = MakeHierarchySchedule(plan);
  EXPECT_EQ(s.samples, (std::vector<uint32_t>{16, 8, 4, 2, 2}));
  EXPECT_EQ(s.nmax, 32u);
  // Per pixel, the maps of its samples are all different: level-l tasks use maps M_l .. M_l+n_l−1.
  std::map<uint32_t, std::set<uint64_t>> maps_of_pixel;
  for (const TaskSpec& t : HierarchicalStaticTasks(plan, 17, 2, 1)) {
    const Hierarchy h(17, 2, 4, 1);
    for (uint32_t p : h.PointsOf(t.pixels.level, t.pixels.y0, t.pixels.y1))
      EXPECT_TRUE(maps_of_pixel[p].insert(t.map_index).second) << "pixel " << p << " map " << t.map_index;
  }
  const HierarchyStats st = ComputeHierarchyStats(plan, 17, 2);
  EXPECT_EQ(st.nmax, 32u);
  // (2·16 + 1·8 + 2·4 + 4·2 + 8·2) / 17 samples per pixel.
  EXPECT_NEAR(st.navg, 72.0 / 17, 1e-12);
  // Evaluations add the parents: (2·16 + 3·8 + 5·4 + 9·2 + 17·2) / 17.
  EXPECT_NEAR(st.evaluations_per_pixel, 128.0 / 17, 1e-12);
}

// A photon map's low-frequency error in the extreme: map j is off by a constant a_j everywhere.
// Then every detail is exact (Σ w = 1), and every pixel's error is the mean offset of the n0
// level-0 maps: variance σ²/n0 at every pixel, although most pixels used n_l ≪ n0 samples.
TEST(Hierarchical, SmoothFunctionWithPerMapOffsetsHasTheErrorOfTheBaseLevel) {
  for (uint32_t dims : {1u, 2u}) {
    const int w = 33, h = dims == 1 ? 3 : 33;
    const PlanSpec plan = Plan(5, dims, 8, 1);
    auto g = [](uint32_t x, uint32_t y) { return 0.5 + 0.3 * std::sin(0.03 * x) * std::cos(0.02 * y); };
    auto offset = [](uint64_t map) { return 0.1 * Gaussian(HashKey(1, map)); };
    const Render f = [&](uint32_t x, uint32_t y, uint64_t map, uint64_t) { return g(x, y) + offset(map); };
    const HierarchicalAssembly acc = RunPlan(plan, w, h, f);
    double base = 0;
    for (uint64_t j = 0; j < 8; ++j) base += offset(j) / 8;
    ASSERT_GT(std::fabs(base), 1e-3);
    const Image img = acc.Resolve();
    for (uint32_t y = 0; y < uint32_t(h); ++y)
      for (uint32_t x = 0; x < uint32_t(w); ++x)
        ASSERT_NEAR(img.at(x, y).g, g(x, y) + base, 2e-6) << dims << "-D at " << x << "," << y;
    for (uint32_t l = 1; l <= 5; ++l) EXPECT_TRUE(acc.Localized(l).empty()) << "smooth: no localization";
  }
}

// White noise (independent per pixel and map): the exact variance of every pixel follows from
// the plan by linear propagation (F = Σ c·ε over the noise variables ε(map, pixel)); the variance
// measured over 300 trials matches it.
TEST(Hierarchical, WhiteNoiseVarianceMatchesTheExactPropagation) {
  for (uint32_t dims : {1u, 2u}) {
    const int w = 17, h = dims == 1 ? 4 : 17;
    const PlanSpec plan = Plan(4, dims, 8, 2);
    const double sigma = 0.05;
    const Hierarchy hier(w, h, 4, dims);
    const HierarchySchedule s = MakeHierarchySchedule(plan);
    const size_t n = size_t(w) * h;
    // Exact: coefficient vectors over ε(map, pixel), level by level.
    std::vector<std::map<std::pair<uint64_t, uint32_t>, double>> coef(n);
    for (uint32_t l = 0; l <= 4; ++l)
      for (uint32_t p : hier.PointsOf(l, 0, h)) {
        auto& c = coef[p];
        const double inv = 1.0 / s.samples[l];
        const Hierarchy::Parents par = hier.ParentsOf(p);
        for (uint32_t k = 0; k < par.count; ++k)
          for (const auto& [var, v] : coef[par.pixel[k]]) c[var] += par.weight[k] * v;
        for (uint32_t j = 0; j < s.samples[l]; ++j) {
          const uint64_t map = s.map_offset[l] + j;
          c[{map, p}] += inv;
          for (uint32_t k = 0; k < par.count; ++k) c[{map, par.pixel[k]}] -= inv * par.weight[k];
        }
      }
    double exact = 0;
    for (const auto& c : coef)
      for (const auto& [var, v] : c) exact += v * v * sigma * sigma / n;
    // Measured.
    auto g = [](uint32_t x, uint32_t y) { return 0.3 + 0.02 * x + 0.01 * y; };
    const Render f = [&](uint32_t x, uint32_t y, uint64_t map, uint64_t trial) {
      return g(x, y) + sigma * Gaussian(HashKey(trial, map, uint64_t(y) * 1000 + x));
    };
    const int trials = 300;
    std::vector<double> sum(n, 0), sum2(n, 0);
    PlanSpec no_localization = plan;
    no_localization.localize_contrast = 1e9;  // variance of the pure hierarchy
    for (int t = 0; t < trials; ++t) {
      const Image img = RunPlan(no_localization, w, h, f, 1000 + t).Resolve();
      for (size_t p = 0; p < n; ++p) {
        const double e = img[p].g - g(p % w, p / w);
        sum[p] += e;
        sum2[p] += e * e;
      }
    }
    double measured = 0, bias = 0;
    for (size_t p = 0; p < n; ++p) {
      measured += sum2[p] / trials / n;
      bias += sum[p] / trials / n;
    }
    // 300 trials × n pixels (correlated): the mean variance is known to a few per cent.
    EXPECT_NEAR(measured / exact, 1.0, 0.08) << dims << "-D: measured " << measured << " exact " << exact;
    EXPECT_NEAR(bias, 0.0, 3 * std::sqrt(exact / trials)) << "unbiased";
    // The price of the details: against purely white noise the hierarchy is worse than navg
    // direct samples per pixel (each detail also carries its parents' noise); it pays off against
    // the photon map's low-frequency error (the test above).
    const HierarchyStats st = ComputeHierarchyStats(plan, w, h);
    EXPECT_GT(exact, sigma * sigma / st.navg) << dims << "-D";
  }
}

TEST(Hierarchical, LocalizationFiresAtAStepAndNowhereOnARamp) {
  const int w = 65, h = 6;
  const PlanSpec plan = Plan(5, 1, 8, 2);
  auto noisy = [](std::function<double(uint32_t)> g) -> Render {
    return [g](uint32_t x, uint32_t y, uint64_t map, uint64_t) {
      return g(x) + 0.02 * Gaussian(HashKey(map, y, x));
    };
  };
  const HierarchicalAssembly ramp =
      RunPlan(plan, w, h, noisy([](uint32_t x) { return 0.2 + 0.6 * x / 64.0; }));
  for (uint32_t l = 1; l <= 5; ++l) {
    EXPECT_TRUE(ramp.LevelComplete(l));
    EXPECT_TRUE(ramp.Localized(l).empty()) << "level " << l;
    EXPECT_GT(ramp.LevelNoise(l), 0.0);
  }
  std::vector<TaskSpec> step_tasks;
  const HierarchicalAssembly step =
      RunPlan(plan, w, h, noisy([](uint32_t x) { return x <= 40 ? 0.2 : 0.8; }), 0, false, &step_tasks);
  std::set<uint32_t> localized_x;
  for (uint32_t l = 1; l <= 5; ++l)
    for (uint32_t p : step.Localized(l)) localized_x.insert(p % w);
  // The step lies between 40 and 41: the points whose interval straddles it, and only those.
  ASSERT_FALSE(localized_x.empty());
  EXPECT_TRUE(localized_x.count(40) || localized_x.count(41));
  for (uint32_t x : localized_x) EXPECT_TRUE(x > 32 && x < 64) << x;
  // Localization tasks exist (level-0 maps, explicit pixel lists), and at the step the image is
  // right to within the noise of n0 direct samples.
  const bool has_list = std::any_of(step_tasks.begin(), step_tasks.end(), [](const TaskSpec& t) {
    return t.pixels.kind == PixelSubset::Kind::kList;
  });
  EXPECT_TRUE(has_list);
  const Image img = step.Resolve();
  for (uint32_t y = 0; y < uint32_t(h); ++y) {
    EXPECT_NEAR(img.at(40, y).g, 0.2, 0.05);
    EXPECT_NEAR(img.at(41, y).g, 0.8, 0.05);
  }
}

TEST(Hierarchical, PlanIsDeterministicAndMergeOrderIndependentAndIdempotent) {
  const int w = 33, h = 17;
  PlanSpec plan = Plan(4, 2, 4, 1);
  plan.tile_size = 5;  // several row bands per level
  const Render f = [](uint32_t x, uint32_t y, uint64_t map, uint64_t) {
    return (x > 20 ? 0.9 : 0.1) + 0.05 * Gaussian(HashKey(map, y, x)) + 0.01 * y;
  };
  std::vector<TaskSpec> a_tasks, b_tasks;
  const HierarchicalAssembly a = RunPlan(plan, w, h, f, 0, false, &a_tasks);
  const HierarchicalAssembly b = RunPlan(plan, w, h, f, 0, true, &b_tasks);
  ASSERT_EQ(a_tasks.size(), b_tasks.size());
  EXPECT_GT(a_tasks.size(), HierarchicalStaticTasks(plan, w, h, 5).size()) << "the step is localized";
  for (size_t i = 0; i < a_tasks.size(); ++i) {
    EXPECT_EQ(a_tasks[i].task_id, i);
    EXPECT_EQ(a_tasks[i].map_seed, b_tasks[i].map_seed);
    EXPECT_EQ(a_tasks[i].pixels.list, b_tasks[i].pixels.list);
  }
  EXPECT_TRUE(a == b);
  const Image ia = a.Resolve(), ib = b.Resolve();
  for (size_t p = 0; p < ia.size(); ++p) ASSERT_TRUE(ia[p] == ib[p]) << p;
  // A task merged twice changes nothing.
  HierarchicalAssembly c = a;
  const TaskSpec& t = a_tasks[3];
  const std::vector<uint32_t> px = PixelsOf(t.pixels, w, h);
  EXPECT_FALSE(c.Add(t, px, RenderTask(t, px, w, f, 0), 1));
  EXPECT_TRUE(c == a);
  // The same job seed gives the same tasks; another seed other maps.
  EXPECT_NE(HierarchicalStaticTasks(plan, w, h, 6)[0].map_seed, a_tasks[0].map_seed);
}

// The farm's Accumulator holds the assembly for a hierarchical job: same image, and checkpoints
// round-trip bit for bit (and refuse a job whose plan is not hierarchical).
TEST(Hierarchical, AccumulatorMergesAndCheckpointsTheAssembly) {
  const int w = 17, h = 9;
  const PlanSpec plan = Plan(3, 2, 4, 1);
  const Render f = [](uint32_t x, uint32_t y, uint64_t map, uint64_t) {
    return 0.5 + 0.01 * x + 0.05 * Gaussian(HashKey(map, y, x));
  };
  std::vector<TaskSpec> tasks;
  const HierarchicalAssembly direct = RunPlan(plan, w, h, f, 0, false, &tasks);
  Accumulator acc(plan, w, h, kDefaultProgressiveAlpha);
  for (const TaskSpec& t : tasks) {
    const std::vector<uint32_t> px = PixelsOf(t.pixels, w, h);
    acc.AddValidated(t, px, RenderTask(t, px, w, f, 0), 1);
  }
  ASSERT_NE(acc.hierarchy(), nullptr);
  EXPECT_TRUE(*acc.hierarchy() == direct);
  EXPECT_EQ(acc.tasks_merged(), tasks.size());
  EXPECT_LT(acc.EstimatedNoiseRms(), 0.0);
  const std::string bytes = acc.Serialize();
  const Accumulator back = Accumulator::Deserialize(bytes, &plan);
  EXPECT_TRUE(back == acc);
  const Image a = acc.Resolve(), b = back.Resolve();
  for (size_t p = 0; p < a.size(); ++p) ASSERT_TRUE(a[p] == b[p]);
  EXPECT_THROW(Accumulator::Deserialize(bytes), InputError);
  EXPECT_THROW(Accumulator::Deserialize(bytes.substr(0, bytes.size() - 3), &plan), InputError);
  PlanSpec other = plan;
  other.levels = 2;
  EXPECT_THROW(Accumulator::Deserialize(bytes, &other), InputError);
}

// HierarchyPart::kIndirect (hierarchical.h, "Parts"): the levels and localization see only the
// map part; the per-pixel part (here a checkerboard, the worst case for a hierarchy: every detail
// would be a discontinuity) comes from its own tasks and is added at assembly. The image must be
// exactly the kAll hierarchy of the map part plus the per-pixel part's mean, localization must
// follow the map part only, and the merge must be order-independent and checkpoint bit for bit.
TEST(Hierarchical, IndirectPartHierarchyOfTheMapPartPlusThePerPixelPart) {
  const int w = 33, h = 17;
  PlanSpec all = Plan(4, 2, 4, 1);
  all.tile_size = 5;
  PlanSpec split = all;
  split.hierarchy_part = HierarchyPart::kIndirect;
  split.direct_samples = 3;
  // Map part: a step at x = 20 (localized) plus per-map noise.
  const Render mapped = [](uint32_t x, uint32_t y, uint64_t map, uint64_t) {
    return (x > 20 ? 0.9 : 0.1) + 0.05 * Gaussian(HashKey(map, y, x)) + 0.01 * y;
  };
  auto checker = [](uint32_t x, uint32_t y) { return ((x + y) % 2) ? 0.7 : 0.05; };
  // A task's sums: the checkerboard for the per-pixel part, the map part rendered otherwise.
  auto sums_of = [&](const TaskSpec& t, const std::vector<uint32_t>& px) {
    const uint32_t n = t.sample_end - t.sample_begin;
    std::vector<float> sums;
    if (t.part == RadiancePart::kUnmapped) {
      for (uint32_t p : px)
        for (int c = 0; c < 3; ++c) sums.push_back(float(checker(p % w, p / w) * n));
    } else {
      sums = RenderTask(t, px, w, mapped, 0);
    }
    return sums;
  };
  auto run = [&](bool reverse, std::vector<TaskSpec>* all_tasks) {
    HierarchicalAssembly acc(split, w, h);
    size_t done = 0;
    for (;;) {
      std::vector<TaskSpec> tasks = HierarchicalTasks(split, w, h, 5, acc);
      if (tasks.size() == done) {
        *all_tasks = tasks;
        return acc;
      }
      std::vector<TaskSpec> batch(tasks.begin() + done, tasks.end());
      if (reverse) std::reverse(batch.begin(), batch.end());
      for (const TaskSpec& t : batch) {
        const std::vector<uint32_t> px = PixelsOf(t.pixels, w, h);
        acc.Add(t, px, sums_of(t, px), t.sample_end - t.sample_begin);
      }
      done = tasks.size();
    }
  };
  std::vector<TaskSpec> tasks, reversed_tasks, all_tasks;
  const HierarchicalAssembly a = run(false, &tasks);
  const HierarchicalAssembly b = run(true, &reversed_tasks);
  const HierarchicalAssembly reference = RunPlan(all, w, h, mapped, 0, false, &all_tasks);
  // Tasks: one per-pixel task per row band first (3 samples, all pixels once), then the kAll plan's
  // tasks with the map part only, localization included (the same points: the checkerboard is not
  // in the hierarchy).
  const size_t bands = (h + 4) / 5;
  ASSERT_EQ(tasks.size(), all_tasks.size() + bands);
  std::vector<uint32_t> covered(size_t(w) * h, 0);
  for (size_t i = 0; i < tasks.size(); ++i) {
    EXPECT_EQ(tasks[i].task_id, i);
    EXPECT_EQ(tasks[i].part, i < bands ? RadiancePart::kUnmapped : RadiancePart::kMapped) << i;
    if (i < bands) {
      EXPECT_EQ(tasks[i].sample_end - tasks[i].sample_begin, 3u);
      for (uint32_t p : PixelsOf(tasks[i].pixels, w, h)) ++covered[p];
    } else {
      EXPECT_EQ(tasks[i].map_seed, all_tasks[i - bands].map_seed);
      EXPECT_EQ(tasks[i].pixels.list, all_tasks[i - bands].pixels.list);
    }
  }
  for (uint32_t c : covered) ASSERT_EQ(c, 1u);
  for (uint32_t l = 1; l <= 4; ++l) EXPECT_EQ(a.Localized(l), reference.Localized(l)) << l;
  EXPECT_FALSE(reference.Localized(1).empty() && reference.Localized(2).empty() &&
               reference.Localized(3).empty() && reference.Localized(4).empty())
      << "the map part's step is localized";
  const Image ia = a.Resolve(), ib = b.Resolve(), ir = reference.Resolve();
  for (uint32_t p = 0; p < ia.size(); ++p) {
    ASSERT_TRUE(ia[p] == ib[p]) << "merge order, pixel " << p;
    ASSERT_NEAR(ia[p].g, ir[p].g + checker(p % w, p / w), 1e-6) << p;
  }
  EXPECT_TRUE(a == b);
  // Checkpoints carry the per-pixel part; a plan without it refuses them.
  Accumulator acc(split, w, h, kDefaultProgressiveAlpha);
  for (const TaskSpec& t : tasks) {
    const std::vector<uint32_t> px = PixelsOf(t.pixels, w, h);
    acc.AddValidated(t, px, sums_of(t, px), t.sample_end - t.sample_begin);
  }
  EXPECT_TRUE(*acc.hierarchy() == a);
  const std::string bytes = acc.Serialize();
  EXPECT_TRUE(Accumulator::Deserialize(bytes, &split) == acc);
  EXPECT_THROW(Accumulator::Deserialize(bytes, &all), InputError);
  EXPECT_EQ(PlanExpansionVersion(split), 4u);
  EXPECT_EQ(PlanExpansionVersion(all), 3u);
}

TEST(Hierarchical, InvalidPlansNameTheField) {
  auto err = [](PlanSpec p) {
    try {
      ValidatePlan(p, 16, 16);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(err(Plan(0, 1, 4, 1)).find("plan.hierarchical.levels"), std::string::npos);
  EXPECT_NE(err(Plan(3, 3, 4, 1)).find("plan.hierarchical.dims"), std::string::npos);
  EXPECT_NE(err(Plan(3, 1, 4, 5)).find("plan.hierarchical.min_samples"), std::string::npos);
  EXPECT_NE(err(Plan(3, 1, 4, 1, 0.5)).find("plan.hierarchical.decay"), std::string::npos);
  EXPECT_EQ(err(Plan(3, 1, 4, 1)), "");
  PlanSpec split = Plan(3, 1, 4, 1);
  split.hierarchy_part = HierarchyPart::kIndirect;
  EXPECT_NE(err(split).find("plan.hierarchical.direct_samples_per_pixel"), std::string::npos) << "0 samples";
  split.direct_samples = 2;
  EXPECT_EQ(err(split), "");
  PlanSpec all = Plan(3, 1, 4, 1);
  all.direct_samples = 2;
  EXPECT_NE(err(all).find("plan.hierarchical.direct_samples_per_pixel"), std::string::npos)
      << "without part indirect";
}

}  // namespace
}  // namespace pf
