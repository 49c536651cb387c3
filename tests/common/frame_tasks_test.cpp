// An animation's tasks (common/plan/frame_tasks.h): every frame renders the still image's tasks with
// the same seeds, in its own rows of the stacked image, map by map; only tile plans stack.
#include "common/plan/frame_tasks.h"

#include <gtest/gtest.h>

#include <map>
#include <tuple>

namespace pf {
namespace {

PlanSpec Plan(PlanKind kind) {
  PlanSpec p;
  p.kind = kind;
  p.maps = 3;
  p.samples_per_pixel = 2;
  p.tile_size = 32;
  if (kind == PlanKind::kMultipleMaps) p.tail_tile_size = 16;
  return p;
}

// What a task renders, apart from its id and frame.
auto Rendered(const TaskSpec& t) {
  return std::tuple(t.map_index, t.map_seed, t.pixel_seed, t.pixels.x0, t.pixels.y0, t.pixels.x1, t.pixels.y1,
                    t.sample_begin, t.sample_end, t.round, t.progressive, int(t.part));
}

TEST(FrameTasks, EachFrameRendersTheStillImagesTasksInItsOwnRowsMapByMap) {
  constexpr int kWidth = 80, kHeight = 48;
  constexpr uint32_t kFrames = 5;
  for (PlanKind kind : {PlanKind::kMultipleMaps, PlanKind::kMapsInTurn, PlanKind::kProgressive}) {
    const PlanSpec plan = Plan(kind);
    SCOPED_TRACE(DescribePlan(plan));
    const std::vector<TaskSpec> still = ExpandPlan(plan, kWidth, kHeight, 77);
    const std::vector<TaskSpec> tasks = ExpandFrames(plan, kWidth, kHeight, 77, kFrames);
    ASSERT_EQ(tasks.size(), still.size() * kFrames);
    EXPECT_EQ(CountFrameTasks(plan, kWidth, kHeight, kFrames), tasks.size());
    std::map<uint32_t, std::multiset<decltype(Rendered(still[0]))>> per_frame;
    for (size_t i = 0; i < tasks.size(); ++i) {
      const TaskSpec& t = tasks[i];
      EXPECT_EQ(t.task_id, i);
      ASSERT_LT(t.frame, kFrames);
      // In its frame's rows of the stacked image.
      EXPECT_GE(t.pixels.y0, t.frame * kHeight);
      EXPECT_LE(t.pixels.y1, (t.frame + 1) * kHeight);
      // Map by map: a map's tasks for every frame before the next map's.
      if (i > 0) {
        EXPECT_LE(tasks[i - 1].map_index, t.map_index);
      }
      per_frame[t.frame].insert(Rendered(FrameLocalTask(t, kHeight)));
    }
    std::multiset<decltype(Rendered(still[0]))> expected;
    for (const TaskSpec& t : still) expected.insert(Rendered(t));
    ASSERT_EQ(per_frame.size(), kFrames);
    for (const auto& [frame, rendered] : per_frame) EXPECT_EQ(rendered, expected) << "frame " << frame;
    // One frame is the still image, ids and all.
    const std::vector<TaskSpec> one = ExpandFrames(plan, kWidth, kHeight, 77, 1);
    ASSERT_EQ(one.size(), still.size());
    for (size_t i = 0; i < one.size(); ++i) {
      EXPECT_EQ(one[i].task_id, still[i].task_id);
      EXPECT_EQ(Rendered(one[i]), Rendered(still[i]));
      EXPECT_EQ(one[i].frame, 0u);
    }
  }
}

// A longer plan keeps the shorter one's tasks at their ids (a requeue continues an animation).
TEST(FrameTasks, MorePassesKeepEveryTaskOfFewerAtItsId) {
  PlanSpec shorter = Plan(PlanKind::kProgressive), longer = shorter;
  longer.maps = 5;
  const std::vector<TaskSpec> a = ExpandFrames(shorter, 64, 32, 5, 4), b = ExpandFrames(longer, 64, 32, 5, 4);
  ASSERT_LT(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(Rendered(a[i]), Rendered(b[i])) << i;
    EXPECT_EQ(a[i].frame, b[i].frame) << i;
  }
}

TEST(FrameTasks, OnlyTilePlansStack) {
  EXPECT_EQ(FramesPlanProblem(Plan(PlanKind::kMultipleMaps)), "");
  EXPECT_EQ(FramesPlanProblem(Plan(PlanKind::kMapsInTurn)), "");
  EXPECT_EQ(FramesPlanProblem(Plan(PlanKind::kProgressive)), "");
  EXPECT_NE(FramesPlanProblem(Plan(PlanKind::kSkipping)).find("skipping"), std::string::npos);
  EXPECT_NE(FramesPlanProblem(Plan(PlanKind::kHierarchical)).find("hierarchical"), std::string::npos);
  PlanSpec skipping = Plan(PlanKind::kSkipping);
  skipping.stride = 2;
  EXPECT_THROW(ExpandFrames(skipping, 32, 32, 1, 2), std::logic_error);
}

}  // namespace
}  // namespace pf
