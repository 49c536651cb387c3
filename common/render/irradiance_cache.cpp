#include "common/render/irradiance_cache.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace pf {
namespace {

// Ward 1988's "in front" test with a little slack for the records of one flat surface, whose
// points differ from the tangent plane only by rounding.
constexpr float kInFrontTolerance = 0.01f;

constexpr int kMaxLevel = 31;  // levels_used_ is a 32-bit mask

// Level 0's radius: the smallest R a record can have (R is clamped to it).
float BaseRadius(const IrradianceCacheOptions& o) {
  if (o.min_radius > 0.0f) return o.min_radius;
  return o.max_radius > 0.0f ? o.max_radius / 64.0f : 1e-3f;
}

int64_t CellIndex(float coordinate, float cell) {
  const double i = std::floor(double(coordinate) / double(cell));
  if (!std::isfinite(i)) return 0;  // a non-finite point: any cell (Usable rejects it anyway)
  return int64_t(std::clamp(i, -4.0e15, 4.0e15));
}

uint64_t CellKey(int level, int64_t i, int64_t j, int64_t k) {
  uint64_t h = uint64_t(level) * 0x9E3779B97F4A7C15ull;
  for (int64_t v : {i, j, k}) {
    h ^= uint64_t(v) + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
    h *= 0xBF58476D1CE4E5B9ull;
  }
  return h ^ (h >> 31);
}

}  // namespace

bool IrradianceCache::Usable(const IrradianceRecord& r, const Vec3& x, const Vec3& n, float& weight) const {
  const float cos_n = Dot(n, r.normal);
  if (!(cos_n > 0.0f)) return false;
  const Vec3 d = x - r.position;
  const float distance = Length(d);
  const float error = distance / r.radius + std::sqrt(std::max(0.0f, 1.0f - cos_n));
  if (!(error < options_.error)) return false;
  if (Dot(d, n + r.normal) * 0.5f < -kInFrontTolerance * r.radius) return false;  // x_i in front of x
  weight = 1.0f / std::max(error, 1e-6f);
  return true;
}

std::optional<Rgb> IrradianceCache::InterpolateLinearScan(const Vec3& x, const Vec3& n) const {
  Rgb sum(0.0f);
  double weight_sum = 0.0;
  for (const IrradianceRecord& r : records_) {
    float w = 0.0f;
    if (!Usable(r, x, n, w)) continue;
    sum += r.irradiance * w;
    weight_sum += w;
  }
  if (weight_sum <= 0.0) return std::nullopt;
  return sum * float(1.0 / weight_sum);
}

std::optional<Rgb> IrradianceCache::Interpolate(const Vec3& x, const Vec3& n) const {
  candidates_.clear();
  for (uint32_t used = levels_used_; used != 0; used &= used - 1) {
    const int level = std::countr_zero(used);
    const float cell = CellSize(level);
    const auto it =
        cells_.find(CellKey(level, CellIndex(x.x, cell), CellIndex(x.y, cell), CellIndex(x.z, cell)));
    if (it != cells_.end()) candidates_.insert(candidates_.end(), it->second.begin(), it->second.end());
  }
  // Record order (the linear scan's summation order); unique also drops the rare duplicate
  // of two cells whose hashes collide.
  std::sort(candidates_.begin(), candidates_.end());
  candidates_.erase(std::unique(candidates_.begin(), candidates_.end()), candidates_.end());
  Rgb sum(0.0f);
  double weight_sum = 0.0;
  for (uint32_t i : candidates_) {
    float w = 0.0f;
    if (!Usable(records_[i], x, n, w)) continue;
    sum += records_[i].irradiance * w;
    weight_sum += w;
  }
  if (weight_sum <= 0.0) return std::nullopt;
  return sum * float(1.0 / weight_sum);
}

int IrradianceCache::LevelOf(float radius) const {
  const float base = BaseRadius(options_);
  if (!(radius > base)) return 0;
  return std::clamp(int(std::floor(std::log2(radius / base))), 0, kMaxLevel);
}

float IrradianceCache::CellSize(int level) const {
  // Level L's records have R < 2^{L+1} · base, so they reach less than a · 2^{L+1} · base.
  return std::max(options_.error, 1e-6f) * std::ldexp(BaseRadius(options_), level + 1);
}

void IrradianceCache::Add(const Vec3& x, const Vec3& n, const Rgb& irradiance, double inverse_distance_sum,
                          int hits) {
  // Harmonic mean distance of the hits: R = hits / Σ 1/d.
  float radius =
      inverse_distance_sum > 0.0 ? float(double(hits) / inverse_distance_sum) : options_.max_radius;
  radius = std::clamp(radius, options_.min_radius, std::max(options_.min_radius, options_.max_radius));
  const uint32_t index = uint32_t(records_.size());
  records_.push_back(IrradianceRecord{x, n, irradiance, radius});
  // File the record in every cell of its level that its reach a·R (padded against rounding:
  // Interpolate must find every record the linear scan finds) overlaps: ≤ 3 per axis.
  const int level = LevelOf(radius);
  const float cell = CellSize(level);
  const float reach = std::max(options_.error, 1e-6f) * radius * 1.001f + 1e-6f * cell;
  int64_t lo[3], hi[3];
  for (int axis = 0; axis < 3; ++axis) {
    lo[axis] = CellIndex(x[axis] - reach, cell);
    hi[axis] = CellIndex(x[axis] + reach, cell);
  }
  for (int64_t i = lo[0]; i <= hi[0]; ++i)
    for (int64_t j = lo[1]; j <= hi[1]; ++j)
      for (int64_t k = lo[2]; k <= hi[2]; ++k) cells_[CellKey(level, i, j, k)].push_back(index);
  levels_used_ |= 1u << level;
}

}  // namespace pf
