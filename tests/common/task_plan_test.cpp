// The job → task arithmetic and the merge arithmetic (common/plan): pure functions that the
// coordinator, the worker and the local renderer must agree on exactly.
#include "common/plan/task_plan.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "common/core/error.h"
#include "common/plan/accumulator.h"

namespace pf {
namespace {

// Every pixel must be covered the planned number of times with disjoint sample ranges per map.
void ExpectCoverage(const PlanSpec& plan, int w, int h, uint32_t expected_samples, uint32_t expected_maps) {
  const auto tasks = ExpandPlan(plan, w, h, 42);
  EXPECT_EQ(tasks.size(), CountTasks(plan, w, h));
  std::vector<uint32_t> samples(size_t(w) * h, 0), maps(size_t(w) * h, 0);
  std::set<uint64_t> ids, map_seeds;
  for (const TaskSpec& t : tasks) {
    EXPECT_TRUE(ids.insert(t.task_id).second);
    EXPECT_EQ(t.map_seed, MapSeed(42, t.map_index));
    map_seeds.insert(t.map_seed);
    const auto px = PixelsOf(t.pixels, w, h);
    EXPECT_EQ(px.size(), CountPixels(t.pixels, w, h));
    for (uint32_t p : px) {
      samples[p] += t.sample_end - t.sample_begin;
      maps[p] += 1;
    }
  }
  for (size_t p = 0; p < samples.size(); ++p) {
    ASSERT_EQ(samples[p], expected_samples) << p;
    ASSERT_EQ(maps[p], expected_maps) << p;
  }
}

TEST(TaskPlan, MultipleMapsCoverEveryPixelOncePerMap) {
  ExpectCoverage({.kind = PlanKind::kMultipleMaps, .maps = 3, .samples_per_pixel = 4, .tile_size = 7}, 20, 13,
                 12, 3);
  ExpectCoverage({.kind = PlanKind::kMultipleMaps, .maps = 2, .samples_per_pixel = 1, .tile_size = 0}, 5, 4,
                 2, 2);
}

TEST(TaskPlan, MapsInTurnUseMapIForSampleI) {
  const PlanSpec plan{.kind = PlanKind::kMapsInTurn, .samples_per_pixel = 4, .tile_size = 8};
  ExpectCoverage(plan, 16, 9, 4, 4);
  for (const TaskSpec& t : ExpandPlan(plan, 16, 9, 1)) {
    EXPECT_EQ(t.sample_begin, t.map_index);
    EXPECT_EQ(t.sample_end, t.map_index + 1);
  }
}

// Tail tiles: every pixel still once per map; only the last map's last row of tiles is cut, into
// tiles of at most tail×tail, and those are the expansion's last tasks (leased last).
TEST(TaskPlan, TailTilesCutOnlyTheLastRowOfTheLastMap) {
  struct Case {
    int w, h;
    uint32_t tile, tail;
  };
  for (const Case c :
       {Case{256, 256, 64, 32}, Case{200, 150, 64, 32}, Case{100, 70, 64, 16}, Case{48, 20, 32, 16}}) {
    for (const uint32_t maps : {1u, 2u}) {
      SCOPED_TRACE(std::to_string(c.w) + "x" + std::to_string(c.h) + ", maps " + std::to_string(maps));
      const PlanSpec plain{
          .kind = PlanKind::kMultipleMaps, .maps = maps, .samples_per_pixel = 3, .tile_size = c.tile};
      PlanSpec plan = plain;
      plan.tail_tile_size = c.tail;
      ExpectCoverage(plan, c.w, c.h, 3 * maps, maps);
      const auto tasks = ExpandPlan(plan, c.w, c.h, 42);
      const auto before = ExpandPlan(plain, c.w, c.h, 42);
      const uint32_t cols = (uint32_t(c.w) + c.tile - 1) / c.tile,
                     rows = (uint32_t(c.h) + c.tile - 1) / c.tile;
      const uint32_t last_row_y0 = (rows - 1) * c.tile;
      const size_t per_map = size_t(cols) * rows, kept = per_map * (maps - 1) + size_t(cols) * (rows - 1);
      ASSERT_GT(tasks.size(), before.size());
      // The maps before the last, and the last one's rows above its last: the very same tasks as
      // without tail tiles.
      for (size_t i = 0; i < kept; ++i) {
        EXPECT_EQ(tasks[i].map_index, before[i].map_index);
        EXPECT_EQ(PixelsOf(tasks[i].pixels, c.w, c.h), PixelsOf(before[i].pixels, c.w, c.h));
      }
      // The rest: the last map, inside the last row, at most tail × tail, and the same pixel set
      // as the uncut last row.
      std::vector<uint32_t> cut, uncut;
      for (size_t i = kept; i < tasks.size(); ++i) {
        const PixelSubset& t = tasks[i].pixels;
        EXPECT_EQ(tasks[i].map_index, maps - 1);
        EXPECT_GE(t.y0, last_row_y0);
        EXPECT_LE(t.x1 - t.x0, c.tail);
        EXPECT_LE(t.y1 - t.y0, c.tail);
        for (uint32_t p : PixelsOf(t, c.w, c.h)) cut.push_back(p);
      }
      for (size_t i = kept; i < before.size(); ++i)
        for (uint32_t p : PixelsOf(before[i].pixels, c.w, c.h)) uncut.push_back(p);
      std::sort(cut.begin(), cut.end());
      std::sort(uncut.begin(), uncut.end());
      EXPECT_EQ(cut, uncut);
    }
  }
}

// §4.4: per round S² tasks, each with its own map, each with every S²-th pixel of σ.
TEST(TaskPlan, SkippingIsThesisSection44) {
  const PlanSpec plan{.kind = PlanKind::kSkipping, .samples_per_pixel = 2, .stride = 3, .rounds = 4};
  const int w = 31, h = 17;
  ExpectCoverage(plan, w, h, 2 * 4, 4);
  const auto tasks = ExpandPlan(plan, w, h, 9);
  ASSERT_EQ(tasks.size(), 4u * 9u);
  std::set<uint64_t> maps;
  for (const TaskSpec& t : tasks) maps.insert(t.map_index);
  EXPECT_EQ(maps.size(), tasks.size()) << "a new map for every task";
  // Within a round the subsets partition the image; rounds use different permutations.
  EXPECT_NE(PixelsOf(tasks[0].pixels, w, h), PixelsOf(tasks[9].pixels, w, h));
  const auto perm = PixelPermutation(tasks[0].pixels.permutation_seed, w * h);
  const auto px = PixelsOf(tasks[4].pixels, w, h);
  for (size_t i = 0; i < px.size(); ++i) EXPECT_EQ(px[i], perm[4 + 9 * i]);
}

TEST(TaskPlan, ExpansionIsDeterministicAndSeedDependent) {
  const PlanSpec plan{.kind = PlanKind::kSkipping, .samples_per_pixel = 1, .stride = 2, .rounds = 2};
  const auto a = ExpandPlan(plan, 10, 10, 5), b = ExpandPlan(plan, 10, 10, 5),
             c = ExpandPlan(plan, 10, 10, 6);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].map_seed, b[i].map_seed);
    EXPECT_EQ(PixelsOf(a[i].pixels, 10, 10), PixelsOf(b[i].pixels, 10, 10));
    EXPECT_NE(a[i].map_seed, c[i].map_seed);
  }
}

TEST(TaskPlan, PermutationIsAPermutation) {
  for (uint32_t n : {1u, 2u, 17u, 1000u}) {
    auto p = PixelPermutation(123, n);
    std::sort(p.begin(), p.end());
    for (uint32_t i = 0; i < n; ++i) ASSERT_EQ(p[i], i);
  }
  EXPECT_NE(PixelPermutation(1, 100), PixelPermutation(2, 100));
}

TEST(TaskPlan, InvalidPlansNameTheField) {
  auto message = [](const PlanSpec& p, int w, int h) {
    try {
      ValidatePlan(p, w, h);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({.kind = PlanKind::kMultipleMaps, .maps = 0}, 4, 4).find("plan.multiple_maps.maps"),
            std::string::npos);
  EXPECT_NE(message({.kind = PlanKind::kSkipping, .stride = 0}, 4, 4).find("plan.skipping.stride"),
            std::string::npos);
  EXPECT_NE(message({.kind = PlanKind::kSkipping, .stride = 5}, 4, 4).find("exceeds the number of pixels"),
            std::string::npos);
  EXPECT_NE(
      message({.kind = PlanKind::kSkipping, .stride = 1, .rounds = 0}, 4, 4).find("plan.skipping.rounds"),
      std::string::npos);
  EXPECT_NE(message({.kind = PlanKind::kMapsInTurn, .samples_per_pixel = 0}, 4, 4).find("samples_per_pixel"),
            std::string::npos);
  EXPECT_NE(message({}, 0, 4).find("camera"), std::string::npos);
  // Tail tiles: a multiple of the 16-pixel block below the tile that divides it, multiple maps only.
  const std::string tail = "plan.multiple_maps.tail_tile_size";
  for (const auto& [tile, t] :
       std::vector<std::pair<uint32_t, uint32_t>>{{64, 8}, {64, 24}, {64, 64}, {64, 128}, {0, 16}, {48, 32}})
    EXPECT_NE(
        message({.kind = PlanKind::kMultipleMaps, .tile_size = tile, .tail_tile_size = t}, 64, 64).find(tail),
        std::string::npos)
        << tile << " " << t;
  EXPECT_EQ(message({.kind = PlanKind::kMultipleMaps, .tile_size = 64, .tail_tile_size = 16}, 64, 64),
            "no error");
  for (const PlanKind kind : {PlanKind::kMapsInTurn, PlanKind::kSkipping, PlanKind::kHierarchical})
    EXPECT_NE(
        message({.kind = kind, .tile_size = 64, .tail_tile_size = 32}, 64, 64).find("multiple-maps option"),
        std::string::npos);
}

// A job stored with tail tiles has expansion version 1, one without keeps 0: a coordinator that
// predates tail tiles (it would expand whole tiles under the tail tiles' ids) sets its checkpoint
// aside rather than resume it (server/scheduling/recovery.cpp).
TEST(TaskPlan, TailTilesHaveTheirOwnExpansionVersion) {
  const PlanSpec plain{.kind = PlanKind::kMultipleMaps, .tile_size = 64};
  PlanSpec tail = plain;
  tail.tail_tile_size = 32;
  EXPECT_EQ(PlanExpansionVersion(plain), 0u);
  EXPECT_EQ(PlanExpansionVersion(tail), 1u);
}

// Progressive photon mapping (Knaus & Zwicker 2011): pass p is the multiple-maps plan's map p
// — the same ids, seeds and pixels — marked so that its estimates read the pass's radius.
TEST(TaskPlan, ProgressivePassesAreMultipleMapsWithTheRadiusQuery) {
  const PlanSpec progressive{
      .kind = PlanKind::kProgressive, .maps = 5, .samples_per_pixel = 2, .tile_size = 8};
  PlanSpec multiple = progressive;
  multiple.kind = PlanKind::kMultipleMaps;
  ExpectCoverage(progressive, 20, 13, 10, 5);
  const auto p = ExpandPlan(progressive, 20, 13, 7), m = ExpandPlan(multiple, 20, 13, 7);
  ASSERT_EQ(p.size(), m.size());
  EXPECT_EQ(p.size(), CountTasks(progressive, 20, 13));
  for (size_t i = 0; i < p.size(); ++i) {
    EXPECT_TRUE(p[i].progressive);
    EXPECT_FALSE(m[i].progressive);
    EXPECT_EQ(p[i].task_id, m[i].task_id);
    EXPECT_EQ(p[i].map_index, m[i].map_index);
    EXPECT_EQ(p[i].map_seed, MapSeed(7, p[i].map_index));
    EXPECT_EQ(p[i].pixel_seed, m[i].pixel_seed);
    EXPECT_EQ(PixelsOf(p[i].pixels, 20, 13), PixelsOf(m[i].pixels, 20, 13));
  }
  EXPECT_EQ(PlanExpansionVersion(progressive), 0u);
  EXPECT_EQ(CountRounds(progressive), 1u);
  EXPECT_NE(DescribePlan(progressive).find("5 passes"), std::string::npos);
  for (const auto& [plan, field] : std::vector<std::pair<PlanSpec, std::string>>{
           {{.kind = PlanKind::kProgressive, .maps = 0}, "plan.progressive.passes"},
           {{.kind = PlanKind::kProgressive, .samples_per_pixel = 0}, "plan.progressive.samples_per_pixel"},
           {{.kind = PlanKind::kProgressive, .tile_size = 64, .tail_tile_size = 32},
            "multiple-maps option"}}) {
    try {
      ValidatePlan(plan, 64, 64);
      ADD_FAILURE() << field;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  }
}

TEST(Accumulator, OrderOfMergingDoesNotChangeABit) {
  const int w = 6, h = 5;
  std::mt19937 gen(3);
  std::uniform_real_distribution<float> value(0.0f, 50.0f);
  struct Part {
    std::vector<uint32_t> pixels;
    std::vector<float> sums;
    uint32_t samples;
  };
  std::vector<Part> parts;
  for (int t = 0; t < 40; ++t) {
    Part p;
    for (uint32_t i = 0; i < uint32_t(w * h); ++i)
      if (gen() % 3 == 0) p.pixels.push_back(i);
    for (size_t i = 0; i < p.pixels.size() * 3; ++i)
      p.sums.push_back(value(gen) * (t % 5 == 0 ? 1e-6f : 1.0f));
    p.samples = 1 + gen() % 4;
    parts.push_back(p);
  }
  Accumulator a(w, h), b(w, h);
  for (const Part& p : parts) a.Add(p.pixels, p.sums, p.samples);
  std::shuffle(parts.begin(), parts.end(), gen);
  for (const Part& p : parts) b.Add(p.pixels, p.sums, p.samples);
  const Image ia = a.Resolve(), ib = b.Resolve();
  for (size_t i = 0; i < ia.size(); ++i) ASSERT_TRUE(ia[i] == ib[i]) << i;
  EXPECT_EQ(a.samples_merged(), b.samples_merged());
}

TEST(Accumulator, WeightedAverageAndNoiseEstimate) {
  Accumulator acc(2, 1);
  const std::vector<uint32_t> px = {0, 1};
  acc.Add(px, std::vector<float>{2, 2, 2, 8, 8, 8}, 2);  // means 1 and 4
  EXPECT_LT(acc.EstimatedNoiseRms(), 0.0) << "one map: unknown";
  acc.Add(px, std::vector<float>{3, 3, 3, 12, 12, 12}, 1);  // means 3 and 12
  const Image img = acc.Resolve();
  EXPECT_FLOAT_EQ(img[0].r, 5.0f / 3.0f);
  EXPECT_FLOAT_EQ(img[1].g, 20.0f / 3.0f);
  EXPECT_GT(acc.EstimatedNoiseRms(), 0.0);
}

TEST(Accumulator, RejectsBadResults) {
  using V = ResultCheck::Verdict;
  auto check = [](std::vector<float> sums, uint64_t pixels, uint32_t samples,
                  double bound = std::numeric_limits<double>::infinity()) {
    return Accumulator::ValidateTaskResult(sums, pixels, samples, bound);
  };
  EXPECT_EQ(check(std::vector<float>(5), 2, 1).verdict, V::kInvalid);
  EXPECT_THAT(check({1, 2, NAN}, 1, 1).reason, ::testing::HasSubstr("not finite"));
  EXPECT_EQ(check({1, 2, INFINITY}, 1, 1).verdict, V::kInvalid);
  EXPECT_THAT(check({1, 2, 3e9f}, 1, 1).reason, ::testing::HasSubstr("range"));
  EXPECT_TRUE(check({1, 2, 3}, 1, 1).ok());
  EXPECT_EQ(check({1, 2, 3}, 1, 1).reason, "");
  // Radiance is never negative; -0.0 is zero.
  const ResultCheck negative = check({1, -1e-6f, 3}, 1, 1);
  EXPECT_EQ(negative.verdict, V::kInvalid);
  EXPECT_THAT(negative.reason, ::testing::HasSubstr("rgb_sums[1] = -0.000001 is negative"));
  EXPECT_TRUE(check({-0.0f, 0, 0}, 1, 1).ok());
  // The per-job bound scales with the task's samples: 4 samples × 10 = 40 per channel sum.
  EXPECT_TRUE(check({40, 0, 40, 1, 2, 3}, 2, 4, 10).ok());
  const ResultCheck above = check({40, 0, 40, 1, 40.01f, 3}, 2, 4, 10);
  EXPECT_EQ(above.verdict, V::kImplausible);
  EXPECT_THAT(above.reason,
              ::testing::HasSubstr("rgb_sums[4] = 40.01 exceeds the job's bound 40 (4 samples x 10)"));
  // Invalid beats implausible (a NaN after a value above the bound is still invalid).
  EXPECT_EQ(check({1e6f, NAN, 0}, 1, 1, 10).verdict, V::kInvalid);
  Accumulator acc(2, 2);
  EXPECT_THROW(acc.Add(std::vector<uint32_t>{9}, std::vector<float>{1, 1, 1}, 1), InputError);
  EXPECT_THROW(acc.Add(std::vector<uint32_t>{0}, std::vector<float>{1, -1, 1}, 1), InputError);
}

TEST(Accumulator, SerializeRoundTrip) {
  Accumulator acc(3, 2);
  acc.Add(std::vector<uint32_t>{0, 5}, std::vector<float>{1, 2, 3, 4, 5, 6}, 3);
  const Accumulator back = Accumulator::Deserialize(acc.Serialize());
  EXPECT_TRUE(back == acc);
  std::string bad = acc.Serialize();
  bad.pop_back();
  EXPECT_THROW(Accumulator::Deserialize(bad), InputError);
  EXPECT_THROW(Accumulator::Deserialize("nonsense"), InputError);
}

}  // namespace
}  // namespace pf
