#include "common/plan/hierarchy.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/core/error.h"

namespace pf {

void ValidateHierarchicalPlan(const PlanSpec& plan, int width, int height) {
  if (width <= 0 || height <= 0) throw InputError("camera: width and height must be positive");
  if (plan.levels < 1 || plan.levels > kMaxHierarchyLevels)
    throw InputError("plan.hierarchical.levels: must be in [1, " + std::to_string(kMaxHierarchyLevels) + "]");
  if (plan.dims != 1 && plan.dims != 2) throw InputError("plan.hierarchical.dims: must be 1 or 2");
  if (plan.base_samples < 1) throw InputError("plan.hierarchical.base_samples: must be >= 1");
  if (plan.min_samples < 1 || plan.min_samples > plan.base_samples)
    throw InputError("plan.hierarchical.min_samples: must be in [1, base_samples]");
  if (!(plan.decay >= 1) || !std::isfinite(plan.decay))
    throw InputError("plan.hierarchical.decay: must be a finite number >= 1");
  if (!(plan.localize_threshold >= 0) || !std::isfinite(plan.localize_threshold))
    throw InputError("plan.hierarchical.localize_threshold: must be a finite number >= 0");
  if (!(plan.localize_contrast >= 0) || !std::isfinite(plan.localize_contrast))
    throw InputError("plan.hierarchical.localize_contrast: must be a finite number >= 0");
  if (plan.samples_per_pixel < 1) throw InputError("plan.hierarchical.samples_per_pixel: must be >= 1");
  if (plan.hierarchy_part == HierarchyPart::kIndirect && plan.direct_samples < 1)
    throw InputError("plan.hierarchical.direct_samples_per_pixel: must be >= 1 with part indirect");
  if (plan.hierarchy_part == HierarchyPart::kAll && plan.direct_samples != 0)
    throw InputError(
        "plan.hierarchical.direct_samples_per_pixel: only with part indirect (the levels render all light)");
  uint64_t maps = 0;
  double v = plan.base_samples;
  for (uint32_t l = 0; l <= plan.levels; ++l, v /= plan.decay)
    maps += std::max<uint64_t>(plan.min_samples, uint64_t(std::ceil(v - 1e-9)));
  if (maps > kMaxHierarchyMaps)
    throw InputError("plan.hierarchical: " + std::to_string(maps) + " maps in all (more than " +
                     std::to_string(kMaxHierarchyMaps) + "); use fewer levels or samples");
}

std::vector<std::pair<uint32_t, uint32_t>> RowBands(const PlanSpec& plan, int height) {
  std::vector<std::pair<uint32_t, uint32_t>> bands;
  const uint32_t h = uint32_t(height);
  const uint32_t step = plan.tile_size == 0 ? h : plan.tile_size;
  for (uint32_t y = 0; y < h; y += step) bands.emplace_back(y, std::min(h, y + step));
  return bands;
}

HierarchySchedule MakeHierarchySchedule(const PlanSpec& plan) {
  HierarchySchedule s;
  double v = plan.base_samples;
  uint64_t offset = 0;
  for (uint32_t l = 0; l <= plan.levels; ++l) {
    const uint32_t n = std::max(plan.min_samples, uint32_t(std::ceil(v - 1e-9)));
    s.samples.push_back(n);
    s.map_offset.push_back(offset);
    offset += n;
    v /= plan.decay;
  }
  s.nmax = uint32_t(std::min<uint64_t>(offset, ~uint32_t(0)));
  return s;
}

Hierarchy::Axis Hierarchy::MakeAxis(uint32_t n, uint32_t levels) {
  Axis ax;
  ax.level.assign(n, 0);
  ax.a.assign(n, 0);
  ax.b.assign(n, 0);
  ax.has_level.assign(levels + 1, false);
  ax.has_level[0] = true;
  const uint32_t step = 1u << levels;
  // Iterative bisection (depth ≤ levels): intervals [a, b] with the depth of their midpoint.
  struct Interval {
    uint32_t a, b, depth;
  };
  std::vector<Interval> stack;
  for (uint32_t a = 0; a + 1 < n; a += step) stack.push_back({a, std::min(a + step, n - 1), 1});
  while (!stack.empty()) {
    const Interval iv = stack.back();
    stack.pop_back();
    if (iv.b - iv.a < 2) continue;
    const uint32_t m = iv.a + (iv.b - iv.a) / 2;
    ax.level[m] = uint8_t(iv.depth);
    ax.a[m] = iv.a;
    ax.b[m] = iv.b;
    ax.has_level[iv.depth] = true;
    stack.push_back({iv.a, m, iv.depth + 1});
    stack.push_back({m, iv.b, iv.depth + 1});
  }
  return ax;
}

Hierarchy::Hierarchy(int width, int height, uint32_t levels, uint32_t dims)
    : width_(width), height_(height), levels_(levels), dims_(dims) {
  if (width <= 0 || height <= 0 || levels > kMaxHierarchyLevels || (dims != 1 && dims != 2))
    throw InputError("hierarchy: bad size, levels or dims");
  x_ = MakeAxis(uint32_t(width), levels);
  if (dims == 2) y_ = MakeAxis(uint32_t(height), levels);
}

uint32_t Hierarchy::LevelOf(uint32_t pixel) const {
  const uint32_t x = pixel % uint32_t(width_), y = pixel / uint32_t(width_);
  return dims_ == 1 ? x_.level[x] : std::max(x_.level[x], y_.level[y]);
}

Hierarchy::Parents Hierarchy::ParentsOf(uint32_t pixel) const {
  Parents p;
  const uint32_t w = uint32_t(width_);
  const uint32_t x = pixel % w, y = pixel / w;
  const uint32_t lx = x_.level[x], ly = dims_ == 1 ? 0 : y_.level[y];
  auto t_of = [](uint32_t v, uint32_t a, uint32_t b) { return double(v - a) / double(b - a); };
  if (lx > ly) {
    const double t = t_of(x, x_.a[x], x_.b[x]);
    p.count = 2;
    p.pixel = {y * w + x_.a[x], y * w + x_.b[x], 0, 0};
    p.weight = {1 - t, t, 0, 0};
  } else if (ly > lx) {
    const double t = t_of(y, y_.a[y], y_.b[y]);
    p.count = 2;
    p.pixel = {y_.a[y] * w + x, y_.b[y] * w + x, 0, 0};
    p.weight = {1 - t, t, 0, 0};
  } else if (lx > 0) {
    const double tx = t_of(x, x_.a[x], x_.b[x]), ty = t_of(y, y_.a[y], y_.b[y]);
    const uint32_t ax = x_.a[x], bx = x_.b[x], ay = y_.a[y], by = y_.b[y];
    p.count = 4;
    p.pixel = {ay * w + ax, ay * w + bx, by * w + ax, by * w + bx};
    p.weight = {(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty};
  }
  return p;
}

bool Hierarchy::HasPoints(uint32_t level, uint32_t y0, uint32_t y1) const {
  if (level > levels_ || y0 >= y1) return false;
  if (dims_ == 1) return x_.has_level[level];
  for (uint32_t y = y0; y < y1 && y < uint32_t(height_); ++y) {
    if (y_.level[y] == level) return true;
    if (y_.level[y] < level && x_.has_level[level]) return true;
  }
  return false;
}

std::vector<uint32_t> Hierarchy::PointsOf(uint32_t level, uint32_t y0, uint32_t y1) const {
  std::vector<uint32_t> out;
  const uint32_t w = uint32_t(width_);
  y1 = std::min(y1, uint32_t(height_));
  for (uint32_t y = y0; y < y1; ++y)
    for (uint32_t x = 0; x < w; ++x)
      if (LevelOf(y * w + x) == level) out.push_back(y * w + x);
  return out;
}

std::vector<uint32_t> Hierarchy::TaskPixels(uint32_t level, uint32_t y0, uint32_t y1) const {
  std::vector<uint32_t> out = PointsOf(level, y0, y1);
  if (level == 0) return out;
  const size_t points = out.size();
  for (size_t i = 0; i < points; ++i) {
    const Parents p = ParentsOf(out[i]);
    for (uint32_t k = 0; k < p.count; ++k) out.push_back(p.pixel[k]);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

HierarchyStats ComputeHierarchyStats(const PlanSpec& plan, int width, int height) {
  ValidateHierarchicalPlan(plan, width, height);
  const Hierarchy h(width, height, plan.levels, plan.dims);
  const HierarchySchedule s = MakeHierarchySchedule(plan);
  HierarchyStats st;
  st.nmax = s.nmax;
  st.points.assign(plan.levels + 1, 0);
  const double pixels = double(width) * height;
  double samples = 0, evaluations = 0;
  for (uint32_t l = 0; l <= plan.levels; ++l) {
    st.points[l] = h.PointsOf(l, 0, uint32_t(height)).size();
    samples += double(st.points[l]) * s.samples[l];
    for (const auto& [y0, y1] : RowBands(plan, height))
      if (h.HasPoints(l, y0, y1)) evaluations += double(h.TaskPixels(l, y0, y1).size()) * s.samples[l];
  }
  st.navg = samples * plan.samples_per_pixel / pixels;
  st.evaluations_per_pixel = evaluations * plan.samples_per_pixel / pixels;
  return st;
}

}  // namespace pf
