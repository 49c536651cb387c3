// --plan auto's choice (common/plan/plan_choice.h): the measured rule on the cases it was made for,
// and its invariants over a grid of scenes, budgets, worker counts and stop rules.
#include "common/plan/plan_choice.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "common/core/error.h"

namespace pf {
namespace {
using ::testing::HasSubstr;

PlanChoiceInput Input(int w, int h, uint64_t budget, uint32_t spp, uint32_t workers, bool caustic) {
  PlanChoiceInput in;
  in.width = w;
  in.height = h;
  in.photon_budget = budget;
  in.samples_per_pixel = spp;
  in.workers = workers;
  in.caustic_map = caustic;
  return in;
}

uint64_t MapsOf(const PlanSpec& p) {
  return p.kind == PlanKind::kSkipping ? uint64_t(p.stride) * p.stride * p.rounds : p.maps;
}
uint64_t TotalSpp(const PlanSpec& p) {
  return p.kind == PlanKind::kSkipping ? uint64_t(p.rounds) * p.samples_per_pixel
                                       : uint64_t(p.maps) * p.samples_per_pixel;
}

// The default job (Cornell box: diffuse only, 1M photons, 16 spp, 256²) on 2 workers:
// skipping S 4 (hierarchical-equal-time.md: 0.57× multiple maps' low-frequency error at equal
// time), one round of 16 maps of 62 500 photons: the budget is traced once, not once per worker.
TEST(ChoosePlan, DiffuseSceneOnTwoWorkersSkipsWithTheBudgetSplitOnce) {
  const PlanChoice c = ChoosePlan(Input(256, 256, 1000000, 16, 2, false));
  EXPECT_EQ(c.plan.kind, PlanKind::kSkipping);
  EXPECT_EQ(c.plan.stride, 4u);
  EXPECT_EQ(c.plan.rounds, 1u);
  EXPECT_EQ(c.plan.samples_per_pixel, 16u);
  EXPECT_EQ(c.photons_per_map, 62500u);
  EXPECT_THAT(c.reason, HasSubstr("skipping S 4 x 1 rounds = 16 maps of 62500 photons (budget 1000000)"));
}

// A caustic map needs dense maps (estimators.md): multiple maps, one per worker while each keeps
// >= 100k photons.
TEST(ChoosePlan, CausticSceneUsesOneDenseMapPerWorker) {
  const PlanChoice c = ChoosePlan(Input(256, 256, 1000000, 16, 2, true));
  EXPECT_EQ(c.plan.kind, PlanKind::kMultipleMaps);
  EXPECT_EQ(c.plan.maps, 2u);
  EXPECT_EQ(c.plan.samples_per_pixel, 8u);
  EXPECT_EQ(c.photons_per_map, 500000u);
  EXPECT_THAT(c.reason, HasSubstr("caustic map: multiple maps, 2 maps of 500000 photons"));
  // 16 workers but a budget for 10 maps of 100k: 8 maps (a divisor of the 16 spp), shared.
  const PlanChoice many = ChoosePlan(Input(256, 256, 1000000, 16, 16, true));
  EXPECT_EQ(many.plan.maps, 8u);
  EXPECT_EQ(many.photons_per_map, 125000u);
  EXPECT_THAT(many.reason, HasSubstr("16 workers share a map"));
}

// More workers: more rounds first (denser maps stay), then a larger stride.
TEST(ChoosePlan, MoreWorkersGetMoreTasks) {
  const PlanChoice c64 = ChoosePlan(Input(1024, 1024, 10000000, 16, 64, false));
  EXPECT_EQ(c64.plan.kind, PlanKind::kSkipping);
  EXPECT_EQ(c64.plan.stride, 4u);
  EXPECT_EQ(c64.plan.rounds, 16u);
  EXPECT_GE(MapsOf(c64.plan), 4u * 64);
  const PlanChoice c256 = ChoosePlan(Input(1024, 1024, 100000000, 16, 256, false));
  EXPECT_GT(c256.plan.stride, 4u);
  EXPECT_GE(MapsOf(c256.plan), 4u * 256);
  EXPECT_GE(c256.photons_per_map, kAutoMinPhotonsPerMap);
}

// A stop rule that can end the job early wants whole-image rounds: the most the budget allows.
TEST(ChoosePlan, TimeBudgetAndNoiseTargetTakeMoreRounds) {
  PlanChoiceInput in = Input(256, 256, 1000000, 16, 2, false);
  in.time_budget_seconds = 60;
  const PlanChoice timed = ChoosePlan(in);
  EXPECT_EQ(timed.plan.kind, PlanKind::kSkipping);
  EXPECT_EQ(timed.plan.rounds, 4u);  // 1M / (16 maps × 10k) = 6 rounds at most; 4 divides 16 spp
  EXPECT_EQ(timed.plan.samples_per_pixel, 4u);
  in.time_budget_seconds = 0;
  in.target_noise_rms = 0.01;
  EXPECT_GE(ChoosePlan(in).plan.rounds, 2u);  // the noise estimate needs two maps per pixel
  in.caustic_map = true;
  const PlanChoice caustic = ChoosePlan(in);
  EXPECT_EQ(caustic.plan.kind, PlanKind::kMultipleMaps);
  EXPECT_GE(caustic.plan.maps, 2u);
}

// Shipped maps (mapship): one map of the whole budget, tiles for every worker.
TEST(ChoosePlan, ShippedMapsUseOneLargeMap) {
  PlanChoiceInput in = Input(256, 256, 1000000, 16, 8, false);
  in.maps_can_be_shipped = true;
  const PlanChoice c = ChoosePlan(in);
  EXPECT_EQ(c.plan.kind, PlanKind::kMultipleMaps);
  EXPECT_EQ(c.plan.maps, 1u);
  EXPECT_EQ(c.photons_per_map, 1000000u);
  EXPECT_GE(CountTasks(c.plan, 256, 256), 4u * 8);
}

TEST(ChoosePlan, SmallBudgetsAndThePathTracer) {
  // 50k photons: S 2 (4 maps of 12.5k) is all the budget allows.
  const PlanChoice small = ChoosePlan(Input(256, 256, 50000, 16, 2, false));
  EXPECT_EQ(small.plan.kind, PlanKind::kSkipping);
  EXPECT_EQ(small.plan.stride, 2u);
  EXPECT_EQ(small.photons_per_map, 12500u);
  // 20k: too small to skip; two maps of 10k.
  const PlanChoice tiny = ChoosePlan(Input(256, 256, 20000, 16, 2, false));
  EXPECT_EQ(tiny.plan.kind, PlanKind::kMultipleMaps);
  EXPECT_EQ(tiny.plan.maps, 2u);
  EXPECT_THAT(tiny.reason, HasSubstr("budget too small to skip"));
  PlanChoiceInput path = Input(256, 256, 0, 16, 4, false);
  path.photon_map = false;
  const PlanChoice p = ChoosePlan(path);
  EXPECT_EQ(p.plan.kind, PlanKind::kMultipleMaps);
  EXPECT_EQ(p.plan.maps, 1u);
  EXPECT_EQ(p.photons_per_map, 0u);
  EXPECT_GE(CountTasks(p.plan, 256, 256), 16u);
}

TEST(ChoosePlan, InvalidInputNamesTheField) {
  auto message = [](PlanChoiceInput in) {
    try {
      ChoosePlan(in);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  PlanChoiceInput in = Input(256, 256, 1000, 16, 0, false);
  EXPECT_THAT(message(in), HasSubstr("plan.auto.workers"));
  in = Input(256, 256, 1000, 0, 1, false);
  EXPECT_THAT(message(in), HasSubstr("plan.auto.samples_per_pixel"));
  in = Input(256, 256, 0, 4, 1, false);
  EXPECT_THAT(message(in), HasSubstr("settings.photon_map.photons"));
}

// Over a grid: a valid plan, never hierarchical, exactly the asked samples per pixel, within
// the budget, maps as dense as the rule promises, tasks within the per-task pixel limit.
TEST(ChoosePlan, InvariantsOverScenesWorkersBudgetsAndStopRules) {
  int cases = 0;
  for (auto [w, h] : {std::pair{64, 48}, std::pair{256, 256}, std::pair{1920, 1080}, std::pair{3840, 2160}})
    for (uint64_t budget : {uint64_t(20000), uint64_t(200000), uint64_t(1000000), uint64_t(10000000)})
      for (uint32_t spp : {1u, 4u, 16u, 64u})
        for (uint32_t workers : {1u, 2u, 8u, 100u, 256u})
          for (bool caustic : {false, true})
            for (int stop = 0; stop < 3; ++stop) {
              PlanChoiceInput in = Input(w, h, budget, spp, workers, caustic);
              if (stop == 1) in.time_budget_seconds = 30;
              if (stop == 2) in.target_noise_rms = 0.01;
              const PlanChoice c = ChoosePlan(in);
              const std::string what = c.reason;
              ASSERT_NO_THROW(ValidatePlan(c.plan, w, h)) << what;
              EXPECT_NE(c.plan.kind, PlanKind::kHierarchical);
              EXPECT_EQ(TotalSpp(c.plan), spp) << what;
              EXPECT_LE(MapsOf(c.plan) * c.photons_per_map, budget) << what;
              const uint64_t floor = caustic ? kAutoMinCausticPhotonsPerMap : kAutoMinPhotonsPerMap;
              if (budget >= floor) {
                EXPECT_GE(c.photons_per_map, floor) << what;
              }
              if (caustic) {
                EXPECT_EQ(c.plan.kind, PlanKind::kMultipleMaps) << what;
              }
              const uint64_t pixels = uint64_t(w) * uint64_t(h);
              const uint64_t task_pixels = c.plan.kind == PlanKind::kSkipping
                                               ? (pixels + c.plan.stride * c.plan.stride - 1) /
                                                     (uint64_t(c.plan.stride) * c.plan.stride)
                                               : uint64_t(c.plan.tile_size) * c.plan.tile_size;
              EXPECT_LE(task_pixels, kAutoMaxPixelsPerTask) << what;
              EXPECT_EQ(ChoosePlan(in).reason, c.reason) << "deterministic";
              ++cases;
            }
  EXPECT_EQ(cases, 4 * 4 * 4 * 5 * 2 * 3);
}

}  // namespace
}  // namespace pf
