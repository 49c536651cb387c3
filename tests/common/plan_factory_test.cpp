// common/plan/plan_factory.h: every plan kind has an entry and every name builds a valid plan;
// an unknown name lists the known ones; each plan refuses its own invalid parameter, naming the
// job's field; DescribePlan and ValidatePlan go through the entries.

#include "common/plan/plan_factory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "tests/util/input_error.h"

namespace pf {
namespace {

using pf::testing::InputErrorOf;
using ::testing::HasSubstr;

TEST(PlanFactory, EveryPlanKindHasOneEntry) {
  // pf render --plan's names (client/render_args.cpp lists them after `auto`) and the kinds.
  EXPECT_EQ(Plans().Names(), (std::vector<std::string>{"multiple-maps", "maps-in-turn", "skipping",
                                                       "hierarchical", "progressive"}));
  std::set<PlanKind> kinds;
  for (const PlanEntry& e : Plans().entries()) {
    EXPECT_TRUE(kinds.insert(e.kind).second) << e.name;
    EXPECT_EQ(&Plans().FindKind(e.kind), &e);
  }
  for (PlanKind k : {PlanKind::kMultipleMaps, PlanKind::kMapsInTurn, PlanKind::kSkipping,
                     PlanKind::kHierarchical, PlanKind::kProgressive})
    EXPECT_EQ(Plans().FindKind(k).kind, k);
}

TEST(PlanFactory, EveryRegisteredNameBuildsAndDescribesItself) {
  for (const std::string& name : Plans().Names()) {
    const PlanSpec plan = MakePlan(name, PlanSpec{}, 64, 64);
    EXPECT_EQ(plan.kind, Plans().Find(name, "plan").kind);
    EXPECT_EQ(DescribePlan(plan), Plans().Find(name, "plan").describe(plan));
    EXPECT_FALSE(ExpandPlan(plan, 64, 64, 1).empty()) << name;
  }
  EXPECT_THAT(DescribePlan(MakePlan("skipping", PlanSpec{.stride = 2, .rounds = 3}, 8, 8)),
              HasSubstr("skipping: S=2, 3 rounds"));
}

TEST(PlanFactory, UnknownNameListsTheKnownOnes) {
  EXPECT_THAT(InputErrorOf([] { MakePlan("lightcuts", PlanSpec{}, 8, 8); }),
              HasSubstr("plan: no plan is called 'lightcuts' (known: multiple-maps, maps-in-turn, skipping, "
                        "hierarchical or progressive)"));
}

void ExpectRefused(const std::string& name, const PlanSpec& parameters, const std::string& field) {
  EXPECT_THAT(InputErrorOf([&] { MakePlan(name, parameters, 16, 16); }), HasSubstr(field));
}

TEST(PlanFactory, EachPlanRefusesItsOwnInvalidParameterNamingIt) {
  ExpectRefused("multiple-maps", PlanSpec{.maps = 0}, "plan.multiple_maps.maps");
  ExpectRefused("maps-in-turn", PlanSpec{.samples_per_pixel = 0}, "plan.maps_in_turn.samples_per_pixel");
  ExpectRefused("skipping", PlanSpec{.stride = 17}, "plan.skipping.stride");
  ExpectRefused("hierarchical", PlanSpec{.levels = 0}, "plan.hierarchical");
  // Each reads only its own: a maps count of 0 means nothing to the skipping plan.
  EXPECT_NO_THROW(MakePlan("skipping", PlanSpec{.maps = 0}, 16, 16));
}

}  // namespace
}  // namespace pf
