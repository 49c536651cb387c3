#pragma once
// The structure and the schedule of the hierarchical plan (Wald 1999, §4.5): which level each
// pixel has and which parents, and how many samples and which maps each level gets. What they are
// and why: hierarchical.h, "Structure" and "Schedule"; the plan's tasks and their assembly are
// there too.

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/plan/task_plan.h"

namespace pf {

// Levels 0..L of a hierarchy: L at most this.
inline constexpr uint32_t kMaxHierarchyLevels = 16;
// Maps of all levels together (Nmax): at most this.
inline constexpr uint32_t kMaxHierarchyMaps = 1u << 16;

// Throws InputError, naming the setting, unless the plan's hierarchy parameters and the image size
// make a hierarchy of at most kMaxHierarchyMaps maps.
void ValidateHierarchicalPlan(const PlanSpec& plan, int width, int height);

// The row bands [y0, y1) the plan's tasks cover (one band with tile_size 0).
std::vector<std::pair<uint32_t, uint32_t>> RowBands(const PlanSpec& plan, int height);

struct HierarchySchedule {
  std::vector<uint32_t> samples;     // n_l, l = 0..L
  std::vector<uint64_t> map_offset;  // M_l: first map of level l
  uint32_t nmax = 0;                 // Σ n_l
};
HierarchySchedule MakeHierarchySchedule(const PlanSpec& plan);

class Hierarchy {
 public:
  Hierarchy(int width, int height, uint32_t levels, uint32_t dims);

  struct Parents {
    uint32_t count = 0;
    std::array<uint32_t, 4> pixel{};
    std::array<double, 4> weight{};
  };
  uint32_t LevelOf(uint32_t pixel) const;
  Parents ParentsOf(uint32_t pixel) const;
  // The level-l points with row in [y0, y1), ascending.
  std::vector<uint32_t> PointsOf(uint32_t level, uint32_t y0, uint32_t y1) const;
  // Those points and their parents, ascending and unique: a detail task's pixel set.
  std::vector<uint32_t> TaskPixels(uint32_t level, uint32_t y0, uint32_t y1) const;
  // Whether any row of [y0, y1) has a level-l point.
  bool HasPoints(uint32_t level, uint32_t y0, uint32_t y1) const;

  uint32_t levels() const { return levels_; }
  uint32_t dims() const { return dims_; }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  struct Axis {
    std::vector<uint8_t> level;
    std::vector<uint32_t> a, b;  // parents along the axis (level > 0)
    std::vector<bool> has_level;
  };
  static Axis MakeAxis(uint32_t n, uint32_t levels);
  int width_, height_;
  uint32_t levels_, dims_;
  Axis x_, y_;
};

struct HierarchyStats {
  uint32_t nmax = 0;
  double navg = 0;                   // samples per pixel (its own samples; localization excluded)
  double evaluations_per_pixel = 0;  // rendered pixel samples per pixel, parents included
  std::vector<uint64_t> points;      // per level
};
HierarchyStats ComputeHierarchyStats(const PlanSpec& plan, int width, int height);

}  // namespace pf
