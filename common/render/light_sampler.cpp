#include "common/render/light_sampler.h"

#include <algorithm>

namespace pf {

LightSampler::LightSampler(const EmbreeScene& scene) : scene_(&scene) {
  const SceneDescription& s = scene.description();
  select_prob_by_tri_.assign(s.triangles.size(), 0.0f);
  std::vector<double> weights;
  for (uint32_t t = 0; t < s.triangles.size(); ++t) {
    const Material& m = s.materials[s.triangle_material[t]];
    if (!m.IsEmissive()) continue;
    const float area = scene.triangle_area(t);
    if (!(area > 0.0f)) continue;
    const double w = double(kPi) * area * std::max(m.emission.Luminance(), 1e-6f * m.emission.Max());
    if (!(w > 0.0)) continue;
    triangles_.push_back(t);
    weights.push_back(w);
    total_power_ += m.emission * (kPi * area);
  }
  double total = 0;
  for (double w : weights) total += w;
  cdf_.resize(weights.size());
  double acc = 0;
  for (size_t i = 0; i < weights.size(); ++i) {
    acc += weights[i];
    cdf_[i] = float(acc / total);
    select_prob_by_tri_[triangles_[i]] = float(weights[i] / total);
  }
  if (!cdf_.empty()) cdf_.back() = 1.0f;
}

LightSample LightSampler::Sample(float u_select, float u1, float u2) const {
  const size_t i = std::min<size_t>(std::upper_bound(cdf_.begin(), cdf_.end(), u_select) - cdf_.begin(),
                                    cdf_.size() - 1);
  const uint32_t tri = triangles_[i];
  const SceneDescription& s = scene_->description();
  const auto& t = s.triangles[tri];
  LightSample ls;
  ls.position = SampleTriangle(s.positions[t[0]], s.positions[t[1]], s.positions[t[2]], u1, u2);
  ls.normal = scene_->triangle_normal(tri);
  ls.radiance = s.materials[s.triangle_material[tri]].emission;
  ls.triangle = tri;
  ls.light = s.triangle_light.empty() ? 0 : s.triangle_light[tri];
  ls.pdf_area = select_prob_by_tri_[tri] / scene_->triangle_area(tri);
  return ls;
}

float LightSampler::PdfArea(uint32_t tri) const {
  const float p = select_prob_by_tri_[tri];
  return p > 0.0f ? p / scene_->triangle_area(tri) : 0.0f;
}

}  // namespace pf
