#include "common/plan/hierarchical.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "common/core/error.h"
#include "common/core/rng.h"

namespace pf {
namespace {

constexpr double kFixedScale = 4294967296.0;  // 2^32, as the Accumulator
constexpr double kMadToSigma = 1.4826;        // MAD of a normal distribution × this = σ
constexpr uint64_t kUnmappedTag = 0x6c6974;   // "lit": the pixel streams of the emission + direct light tasks

double Lum(double r, double g, double b) {
  return 0.2126 * r + 0.7152 * g + 0.0722 * b;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + mid));
  return m;
}

TaskSpec MakeTask(uint64_t id, uint32_t level, uint64_t map, uint64_t job_seed, const PlanSpec& plan) {
  TaskSpec t;
  t.task_id = id;
  t.round = level;
  t.map_index = map;
  t.map_seed = MapSeed(job_seed, map);
  t.pixel_seed = PixelSeed(job_seed, map);
  t.sample_begin = 0;
  t.sample_end = plan.samples_per_pixel;
  return t;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Tasks

std::vector<TaskSpec> HierarchicalStaticTasks(const PlanSpec& plan, int width, int height,
                                              uint64_t job_seed) {
  ValidateHierarchicalPlan(plan, width, height);
  const Hierarchy h(width, height, plan.levels, plan.dims);
  const HierarchySchedule s = MakeHierarchySchedule(plan);
  const auto bands = RowBands(plan, height);
  std::vector<TaskSpec> tasks;
  const bool split = plan.hierarchy_part == HierarchyPart::kIndirect;
  if (split) {
    // Emission and direct light per pixel (header, "Parts"), first: a time budget that stops the
    // hierarchy early still has them. Their map index is the first level-0 map, read only by
    // PhotonDirect's light choice (§4.2.3) and built anyway; independent per-pixel streams of
    // their own (not map 0's: that map's level-0 samples draw from PixelSeed(job_seed, 0)).
    for (size_t b = 0; b < bands.size(); ++b) {
      TaskSpec t = MakeTask(tasks.size(), 0, s.map_offset[0], job_seed, plan);
      t.pixel_seed = HashKey(job_seed, kUnmappedTag, b);
      t.sample_end = plan.direct_samples;
      t.part = RadiancePart::kUnmapped;
      t.pixels.kind = PixelSubset::Kind::kTile;
      t.pixels.x0 = 0;
      t.pixels.x1 = uint32_t(width);
      t.pixels.y0 = bands[b].first;
      t.pixels.y1 = bands[b].second;
      tasks.push_back(std::move(t));
    }
  }
  // Level-major, then map, then band: the bands of one map are adjacent (map affinity), and the
  // coarse levels (which localization and the fine levels' interpolation need) come first.
  for (uint32_t l = 0; l <= plan.levels; ++l)
    for (uint32_t j = 0; j < s.samples[l]; ++j)
      for (const auto& [y0, y1] : bands) {
        if (!h.HasPoints(l, y0, y1)) continue;
        TaskSpec t = MakeTask(tasks.size(), l, s.map_offset[l] + j, job_seed, plan);
        t.pixels.kind = PixelSubset::Kind::kHierarchyLevel;
        t.pixels.level = l;
        t.pixels.levels = plan.levels;
        t.pixels.dims = plan.dims;
        t.pixels.y0 = y0;
        t.pixels.y1 = y1;
        if (split) t.part = RadiancePart::kMapped;
        tasks.push_back(std::move(t));
      }
  return tasks;
}

uint64_t CountHierarchicalStaticTasks(const PlanSpec& plan, int width, int height) {
  ValidateHierarchicalPlan(plan, width, height);
  const Hierarchy h(width, height, plan.levels, plan.dims);
  const HierarchySchedule s = MakeHierarchySchedule(plan);
  uint64_t n = plan.hierarchy_part == HierarchyPart::kIndirect ? RowBands(plan, height).size() : 0;
  for (uint32_t l = 0; l <= plan.levels; ++l)
    for (const auto& [y0, y1] : RowBands(plan, height))
      if (h.HasPoints(l, y0, y1)) n += s.samples[l];
  return n;
}

std::vector<TaskSpec> HierarchicalTasks(const PlanSpec& plan, int width, int height, uint64_t job_seed,
                                        const HierarchicalAssembly& merged) {
  std::vector<TaskSpec> tasks = HierarchicalStaticTasks(plan, width, height, job_seed);
  for (uint32_t l = 1; l <= plan.levels; ++l)
    if (!merged.LevelComplete(l)) return tasks;
  // Every level is complete: the localized points of all levels, resampled map by map. One task
  // per (level-0 map j, band) holding every level's localized points of the band, so each of the
  // n0 maps is built once for all of them (per level, it was n0 builds per level with localized
  // points: 1024 of a job's 1383 maps in docs/results/hierarchical-equal-time.md). A pixel's
  // samples and the merged sums are the same either way: the image does not change — except with
  // --irradiance-cache, whose per-block caches then hold several levels' points (still
  // deterministic: a task's pixels and their order are a pure function of the plan).
  std::vector<uint32_t> localized;
  for (uint32_t l = 1; l <= plan.levels; ++l) {
    const std::vector<uint32_t> at = merged.Localized(l);
    localized.insert(localized.end(), at.begin(), at.end());
  }
  if (localized.empty()) return tasks;
  std::sort(localized.begin(), localized.end());
  const HierarchySchedule s = MakeHierarchySchedule(plan);
  const auto bands = RowBands(plan, height);
  // Resampled directly with the level-0 maps 0..n0−1: no pixel of level ≥ 1 ever used them.
  for (uint32_t j = 0; j < s.samples[0]; ++j)
    for (const auto& [y0, y1] : bands) {
      const auto lo = std::lower_bound(localized.begin(), localized.end(), y0 * uint32_t(width));
      const auto hi = std::lower_bound(localized.begin(), localized.end(), y1 * uint32_t(width));
      if (lo == hi) continue;
      TaskSpec t = MakeTask(tasks.size(), plan.levels + 1, s.map_offset[0] + j, job_seed, plan);
      t.pixels.kind = PixelSubset::Kind::kList;
      t.pixels.list.assign(lo, hi);
      if (plan.hierarchy_part == HierarchyPart::kIndirect) t.part = RadiancePart::kMapped;
      tasks.push_back(std::move(t));
    }
  return tasks;
}

// ---------------------------------------------------------------------------------------------
// Work (progress and ETA)

uint64_t MapWork(uint64_t photons_per_map) {
  return uint64_t(std::llround(kMapWorkPerPhoton * double(photons_per_map)));
}

std::vector<uint64_t> HierarchicalTaskWork(const PlanSpec& plan, int width, int height,
                                           uint64_t photons_per_map, std::span<const TaskSpec> tasks) {
  const Hierarchy h(width, height, plan.levels, plan.dims);
  const uint64_t map = MapWork(photons_per_map);
  // Every map of a level renders the same band pixels: count them once per (level, band).
  std::map<std::array<uint32_t, 3>, uint64_t> band_pixels;
  std::vector<uint64_t> work;
  work.reserve(tasks.size());
  for (const TaskSpec& t : tasks) {
    uint64_t pixels = 0;
    if (t.pixels.kind == PixelSubset::Kind::kHierarchyLevel) {
      const std::array<uint32_t, 3> key{t.pixels.level, t.pixels.y0, t.pixels.y1};
      auto it = band_pixels.find(key);
      if (it == band_pixels.end())
        it = band_pixels.emplace(key, h.TaskPixels(t.pixels.level, t.pixels.y0, t.pixels.y1).size()).first;
      pixels = it->second;
    } else {
      pixels = CountPixels(t.pixels, width, height);
    }
    // Emission + direct light tasks build no map (unless PhotonDirect, which this estimate ignores).
    work.push_back(pixels * (t.sample_end - t.sample_begin) + (t.part == RadiancePart::kUnmapped ? 0 : map));
  }
  return work;
}

uint64_t ExpectedLocalizationWork(const PlanSpec& plan, int width, int height, uint64_t photons_per_map,
                                  const HierarchicalAssembly* merged) {
  const Hierarchy h(width, height, plan.levels, plan.dims);
  const double g = plan.dims == 1 ? 1.5 : 3.0;
  std::vector<double> points(plan.levels + 1, 0), count(plan.levels + 1, -1);
  for (uint32_t l = 1; l <= plan.levels; ++l) {
    points[l] = double(h.PointsOf(l, 0, uint32_t(height)).size());
    if (merged && merged->LevelComplete(l)) count[l] = double(merged->Localized(l).size());
  }
  double known = 0, weight = 0;
  for (uint32_t l = 1; l <= plan.levels; ++l)
    if (count[l] >= 0) {
      known += count[l];
      weight += std::pow(g, l);
    }
  // Before any level is complete: as if every level-1 point were localized (the most it can show;
  // measured 20-96 %). After: the fit, but at least one localized level-1 point's worth (a level
  // without localized points says little about the finer ones: a thin feature falls between them).
  const double a = weight > 0 ? std::max(1.0 / g, known / weight) : points[1] / g;
  double localized = 0;
  for (uint32_t l = 1; l <= plan.levels; ++l)
    localized += count[l] >= 0 ? count[l] : std::min(points[l], a * std::pow(g, l));
  const HierarchySchedule s = MakeHierarchySchedule(plan);
  const double bands = double(RowBands(plan, height).size());
  // n0 tasks per band with localized points, each its pixels' samples and a map.
  return uint64_t(std::llround(double(s.samples[0]) *
                               (localized * plan.samples_per_pixel +
                                std::min(bands, std::ceil(localized)) * double(MapWork(photons_per_map)))));
}

// ---------------------------------------------------------------------------------------------
// Assembly

HierarchicalAssembly::HierarchicalAssembly(const PlanSpec& plan, int width, int height)
    : plan_(plan), hierarchy_(width, height, plan.levels, plan.dims) {
  ValidateHierarchicalPlan(plan, width, height);
  const size_t n = size_t(width) * height;
  level_tasks_.assign(plan.levels + 1, 0);
  level_tasks_merged_.assign(plan.levels + 1, 0);
  for (const TaskSpec& t : HierarchicalStaticTasks(plan, width, height, 0))
    if (t.part != RadiancePart::kUnmapped) ++level_tasks_[t.round];
  direct_.assign(3 * n, 0);
  direct_samples_.assign(n, 0);
  detail_.assign(3 * n, 0);
  interp_.assign(n, 0);
  detail2_.assign(n, 0);
  detail_maps_.assign(n, 0);
  if (plan.hierarchy_part == HierarchyPart::kIndirect) {
    unmapped_.assign(3 * n, 0);
    unmapped_samples_.assign(n, 0);
  }
}

bool HierarchicalAssembly::Add(const TaskSpec& task, std::span<const uint32_t> pixels,
                               std::span<const float> rgb_sums, uint32_t samples) {
  if (rgb_sums.size() != pixels.size() * 3 || samples == 0)
    throw std::logic_error("HierarchicalAssembly::Add: unvalidated result");
  if (!merged_.insert(task.task_id).second) return false;
  const size_t n = direct_samples_.size();
  for (uint32_t p : pixels)
    if (p >= n) throw InputError("result: pixel index " + std::to_string(p) + " outside the image");
  samples_merged_ += uint64_t(pixels.size()) * samples;
  if (task.part == RadiancePart::kUnmapped) {
    if (unmapped_samples_.empty())
      throw std::logic_error(
          "HierarchicalAssembly::Add: an emission + direct light task in a plan without them");
    for (size_t i = 0; i < pixels.size(); ++i) {
      for (int c = 0; c < 3; ++c)
        unmapped_[3 * size_t(pixels[i]) + c] +=
            int64_t(std::llround(double(rgb_sums[3 * i + c]) * kFixedScale));
      unmapped_samples_[pixels[i]] += samples;
    }
    return true;
  }
  const bool detail = task.pixels.kind == PixelSubset::Kind::kHierarchyLevel && task.pixels.level > 0;
  if (!detail) {
    for (size_t i = 0; i < pixels.size(); ++i) {
      for (int c = 0; c < 3; ++c)
        direct_[3 * size_t(pixels[i]) + c] +=
            int64_t(std::llround(double(rgb_sums[3 * i + c]) * kFixedScale));
      direct_samples_[pixels[i]] += samples;
    }
    if (task.pixels.kind == PixelSubset::Kind::kHierarchyLevel) ++level_tasks_merged_[0];
    return true;
  }
  const uint32_t level = task.pixels.level;
  const uint32_t w = uint32_t(hierarchy_.width());
  const double inv = 1.0 / samples;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const uint32_t p = pixels[i];
    const uint32_t y = p / w;
    if (y < task.pixels.y0 || y >= task.pixels.y1 || hierarchy_.LevelOf(p) != level) continue;  // a parent
    const Hierarchy::Parents par = hierarchy_.ParentsOf(p);
    double interp[3] = {0, 0, 0};
    for (uint32_t k = 0; k < par.count; ++k) {
      const auto it = std::lower_bound(pixels.begin(), pixels.end(), par.pixel[k]);
      if (it == pixels.end() || *it != par.pixel[k])
        throw std::logic_error("HierarchicalAssembly::Add: a parent is missing from the task's pixels");
      const size_t j = size_t(it - pixels.begin());
      for (int c = 0; c < 3; ++c) interp[c] += par.weight[k] * double(rgb_sums[3 * j + c]) * inv;
    }
    double d[3];
    for (int c = 0; c < 3; ++c) {
      d[c] = double(rgb_sums[3 * i + c]) * inv - interp[c];
      detail_[3 * size_t(p) + c] += int64_t(std::llround(d[c] * kFixedScale));
    }
    const double dl = Lum(d[0], d[1], d[2]);
    detail2_[p] += int64_t(std::llround(dl * dl * kFixedScale));
    interp_[p] += int64_t(std::llround(Lum(interp[0], interp[1], interp[2]) * kFixedScale));
    ++detail_maps_[p];
  }
  ++level_tasks_merged_[level];
  return true;
}

bool HierarchicalAssembly::LevelComplete(uint32_t level) const {
  return level < level_tasks_.size() && level_tasks_merged_[level] == level_tasks_[level];
}

HierarchicalAssembly::LevelDetail HierarchicalAssembly::DetailsOf(uint32_t level) const {
  LevelDetail ld;
  ld.points = hierarchy_.PointsOf(level, 0, uint32_t(hierarchy_.height()));
  for (uint32_t p : ld.points) {
    const double cnt = std::max<uint32_t>(1, detail_maps_[p]) * kFixedScale;
    ld.d.push_back(Lum(double(detail_[3 * size_t(p)]), double(detail_[3 * size_t(p) + 1]),
                       double(detail_[3 * size_t(p) + 2])) /
                   cnt);
    ld.interp.push_back(double(interp_[p]) / cnt);
    const uint32_t m = detail_maps_[p];
    if (m >= 2) {  // standard error of the mean detail (luminance), unbiased variance
      const double mean = ld.d.back();
      const double var = std::max(0.0, (double(detail2_[p]) / kFixedScale - m * mean * mean) / (m - 1));
      ld.standard_error.push_back(std::sqrt(var / m));
    }
  }
  return ld;
}

double HierarchicalAssembly::LevelNoise(uint32_t level) const {
  const LevelDetail ld = DetailsOf(level);
  if (!ld.points.empty() && ld.standard_error.size() == ld.points.size()) return Median(ld.standard_error);
  const double med = Median(ld.d);
  std::vector<double> dev(ld.d.size());
  for (size_t i = 0; i < ld.d.size(); ++i) dev[i] = std::fabs(ld.d[i] - med);
  return kMadToSigma * Median(std::move(dev));
}

std::vector<uint32_t> HierarchicalAssembly::Localized(uint32_t level) const {
  std::vector<uint32_t> out;
  if (level == 0 || !LevelComplete(level)) return out;
  const LevelDetail ld = DetailsOf(level);
  const double sigma = LevelNoise(level);
  for (size_t i = 0; i < ld.points.size(); ++i) {
    const double a = std::fabs(ld.d[i]);
    if (a > plan_.localize_threshold * sigma && a > plan_.localize_contrast * std::fabs(ld.interp[i]))
      out.push_back(ld.points[i]);
  }
  return out;
}

Image HierarchicalAssembly::Resolve() const {
  const int width = hierarchy_.width(), height = hierarchy_.height();
  const size_t n = size_t(width) * height;
  std::vector<double> f(3 * n, 0.0);
  for (uint32_t l = 0; l <= plan_.levels; ++l) {
    for (uint32_t p : hierarchy_.PointsOf(l, 0, uint32_t(height))) {
      double* fp = &f[3 * size_t(p)];
      if (l == 0 || direct_samples_[p] > 0) {  // a level-0 point, or localized
        if (direct_samples_[p] == 0) continue;
        const double inv = 1.0 / (kFixedScale * direct_samples_[p]);
        for (int c = 0; c < 3; ++c) fp[c] = double(direct_[3 * size_t(p) + c]) * inv;
        continue;
      }
      const Hierarchy::Parents par = hierarchy_.ParentsOf(p);
      for (uint32_t k = 0; k < par.count; ++k)
        for (int c = 0; c < 3; ++c) fp[c] += par.weight[k] * f[3 * size_t(par.pixel[k]) + c];
      if (detail_maps_[p] > 0) {
        const double inv = 1.0 / (kFixedScale * detail_maps_[p]);
        for (int c = 0; c < 3; ++c) fp[c] += double(detail_[3 * size_t(p) + c]) * inv;
      }
    }
  }
  // HierarchyPart::kIndirect: the hierarchy above is the map part; emission + direct light, the
  // per-pixel mean of their own tasks, is added here.
  for (size_t p = 0; p < unmapped_samples_.size(); ++p) {
    if (unmapped_samples_[p] == 0) continue;
    const double inv = 1.0 / (kFixedScale * unmapped_samples_[p]);
    for (int c = 0; c < 3; ++c) f[3 * p + c] += double(unmapped_[3 * p + c]) * inv;
  }
  Image img(width, height);
  for (size_t p = 0; p < n; ++p) img[p] = Rgb(float(f[3 * p]), float(f[3 * p + 1]), float(f[3 * p + 2]));
  return img;
}

void HierarchicalAssembly::SerializeTo(std::string& out) const {
  ByteWriter w(out);
  w.Put<uint64_t>(direct_samples_.size());
  w.Put<uint64_t>(samples_merged_);
  w.Put<uint64_t>(level_tasks_merged_.size());
  w.PutArray<uint64_t>(level_tasks_merged_);
  w.PutArray<int64_t>(direct_);
  w.PutArray<uint32_t>(direct_samples_);
  w.PutArray<int64_t>(detail_);
  w.PutArray<int64_t>(interp_);
  w.PutArray<int64_t>(detail2_);
  w.PutArray<uint32_t>(detail_maps_);
  // Only in plans that have them (the reader knows the plan): kAll checkpoints are unchanged.
  if (!unmapped_samples_.empty()) {
    w.PutArray<int64_t>(unmapped_);
    w.PutArray<uint32_t>(unmapped_samples_);
  }
  w.Put<uint64_t>(merged_.size());
  for (uint64_t id : merged_) w.Put<uint64_t>(id);
}

void HierarchicalAssembly::DeserializeFrom(ByteReader& r) {
  const uint64_t n = r.Get<uint64_t>();
  if (n != direct_samples_.size()) r.Fail("hierarchy size differs from the job's");
  samples_merged_ = r.Get<uint64_t>();
  if (r.Get<uint64_t>() != level_tasks_merged_.size()) r.Fail("hierarchy levels differ from the job's");
  r.GetArray<uint64_t>(level_tasks_merged_);
  // Per pixel: 3 + 3 + 1 + 1 int64 and 2 uint32; checked before reading (no huge allocation).
  if (r.remaining() < n * (8 * sizeof(int64_t) + 2 * sizeof(uint32_t))) r.Fail("truncated");
  r.GetArray<int64_t>(direct_);
  r.GetArray<uint32_t>(direct_samples_);
  r.GetArray<int64_t>(detail_);
  r.GetArray<int64_t>(interp_);
  r.GetArray<int64_t>(detail2_);
  r.GetArray<uint32_t>(detail_maps_);
  if (!unmapped_samples_.empty()) {
    if (r.remaining() < n * (3 * sizeof(int64_t) + sizeof(uint32_t))) r.Fail("truncated");
    r.GetArray<int64_t>(unmapped_);
    r.GetArray<uint32_t>(unmapped_samples_);
  }
  const uint64_t m = r.Get<uint64_t>();
  if (m > r.remaining() / sizeof(uint64_t)) r.Fail("truncated");
  merged_.clear();
  for (uint64_t i = 0; i < m; ++i) merged_.insert(r.Get<uint64_t>());
  if (r.remaining() != 0) r.Fail("trailing bytes");
  for (uint32_t l = 0; l < level_tasks_merged_.size(); ++l)
    if (level_tasks_merged_[l] > level_tasks_[l]) r.Fail("more tasks merged than the level has");
}

bool HierarchicalAssembly::operator==(const HierarchicalAssembly& o) const {
  return direct_ == o.direct_ && direct_samples_ == o.direct_samples_ && detail_ == o.detail_ &&
         interp_ == o.interp_ && detail2_ == o.detail2_ && detail_maps_ == o.detail_maps_ &&
         unmapped_ == o.unmapped_ && unmapped_samples_ == o.unmapped_samples_ && merged_ == o.merged_ &&
         samples_merged_ == o.samples_merged_ && level_tasks_merged_ == o.level_tasks_merged_;
}

}  // namespace pf
