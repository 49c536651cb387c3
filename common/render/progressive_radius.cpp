#include "common/render/progressive_radius.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/render/job_render_settings.h"

namespace pf {

double ProgressiveRadiusFactor2(double alpha, uint64_t pass) {
  double f = 1.0;
  for (uint64_t i = 1; i <= pass; ++i) f *= (double(i) + alpha) / double(i + 1);
  return f;
}

double DerivedInitialRadius(const Bounds3& b, uint64_t photons, int k) {
  const Vec3 d = b.Diagonal();
  const double area = 2.0 * (double(d.x) * d.y + double(d.y) * d.z + double(d.z) * d.x);
  if (!(area > 0.0) || photons == 0 || k <= 0) return std::max(1e-3 * double(Length(d)), 1e-12);
  return std::sqrt(double(k) * area / (std::numbers::pi * double(photons)));
}

float ProgressivePassRadius(const JobRenderSettings& s, const Bounds3& scene_bounds, uint64_t pass) {
  const double r1 = s.progressive_radius > 0.0f ? double(s.progressive_radius)
                                                : DerivedInitialRadius(scene_bounds, s.photons, s.k);
  return float(r1 * std::sqrt(ProgressiveRadiusFactor2(s.progressive_alpha, pass)));
}

}  // namespace pf
