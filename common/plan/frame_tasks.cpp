#include "common/plan/frame_tasks.h"

#include <stdexcept>

namespace pf {

std::string FramesPlanProblem(const PlanSpec& plan) {
  switch (plan.kind) {
    case PlanKind::kMultipleMaps:
    case PlanKind::kMapsInTurn:
    case PlanKind::kProgressive:
      return "";
    case PlanKind::kSkipping:
      return "the skipping plan permutes the pixels of one image; an animation renders with multiple-maps, "
             "maps-in-turn or progressive";
    case PlanKind::kHierarchical:
      return "the hierarchical plan builds its levels on one image; an animation renders with multiple-maps, "
             "maps-in-turn or progressive";
  }
  return "unknown plan";
}

uint64_t CountFrameTasks(const PlanSpec& plan, int width, int height, uint32_t frames) {
  return CountTasks(plan, width, height) * frames;
}

std::vector<TaskSpec> ExpandFrames(const PlanSpec& plan, int width, int height, uint64_t seed,
                                   uint32_t frames) {
  std::vector<TaskSpec> still = ExpandPlan(plan, width, height, seed);
  if (frames <= 1) return still;
  if (const std::string problem = FramesPlanProblem(plan); !problem.empty()) throw std::logic_error(problem);
  std::vector<TaskSpec> tasks;
  tasks.reserve(still.size() * frames);
  for (size_t begin = 0; begin < still.size();) {
    size_t end = begin;
    while (end < still.size() && still[end].map_index == still[begin].map_index) ++end;
    for (uint32_t f = 0; f < frames; ++f)
      for (size_t i = begin; i < end; ++i) {
        TaskSpec t = still[i];
        if (t.pixels.kind != PixelSubset::Kind::kTile)
          throw std::logic_error("ExpandFrames: a task is not a tile");
        t.task_id = tasks.size();
        t.frame = f;
        t.pixels.y0 += f * uint32_t(height);
        t.pixels.y1 += f * uint32_t(height);
        tasks.push_back(std::move(t));
      }
    begin = end;
  }
  return tasks;
}

TaskSpec FrameLocalTask(const TaskSpec& task, int height) {
  TaskSpec t = task;
  t.pixels.y0 -= task.frame * uint32_t(height);
  t.pixels.y1 -= task.frame * uint32_t(height);
  return t;
}

}  // namespace pf
