#include "common/render/irradiance_cache.h"

#include <algorithm>
#include <cmath>

namespace pf {
namespace {

// Ward 1988's "in front" test with a little slack for the records of one flat surface, whose
// points differ from the tangent plane only by rounding.
constexpr float kInFrontTolerance = 0.01f;

}  // namespace

std::optional<Rgb> IrradianceCache::Interpolate(const Vec3& x, const Vec3& n) const {
  const float a = options_.error;
  Rgb sum(0.0f);
  double weight_sum = 0.0;
  for (const IrradianceRecord& r : records_) {
    const float cos_n = Dot(n, r.normal);
    if (!(cos_n > 0.0f)) continue;
    const Vec3 d = x - r.position;
    const float distance = Length(d);
    const float error = distance / r.radius + std::sqrt(std::max(0.0f, 1.0f - cos_n));
    if (!(error < a)) continue;
    if (Dot(d, n + r.normal) * 0.5f < -kInFrontTolerance * r.radius) continue;  // x_i in front of x
    const float w = 1.0f / std::max(error, 1e-6f);
    sum += r.irradiance * w;
    weight_sum += w;
  }
  if (weight_sum <= 0.0) return std::nullopt;
  return sum * float(1.0 / weight_sum);
}

void IrradianceCache::Add(const Vec3& x, const Vec3& n, const Rgb& irradiance, double inverse_distance_sum,
                          int hits) {
  // Harmonic mean distance of the hits: R = hits / Σ 1/d.
  float radius =
      inverse_distance_sum > 0.0 ? float(double(hits) / inverse_distance_sum) : options_.max_radius;
  radius = std::clamp(radius, options_.min_radius, std::max(options_.min_radius, options_.max_radius));
  records_.push_back(IrradianceRecord{x, n, irradiance, radius});
}

}  // namespace pf
