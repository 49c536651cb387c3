#include "common/lights/light_sampler.h"

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

  // Group the emitting triangles by light id.
  const uint32_t num_ids = s.num_lights;
  light_index_by_id_.assign(size_t(num_ids) + 1, uint32_t(-1));
  for (size_t i = 0; i < triangles_.size(); ++i) {
    const uint32_t tri = triangles_[i];
    const uint32_t id = s.triangle_light.empty() ? kNoLight : s.triangle_light[tri];
    const size_t slot = (id == kNoLight || id >= num_ids) ? num_ids : id;
    if (light_index_by_id_[slot] == uint32_t(-1)) {
      light_index_by_id_[slot] = uint32_t(lights_.size());
      lights_.push_back(LightGroup{id, {}, {}, {}, Rgb(0.0f)});
    }
    LightGroup& g = lights_[light_index_by_id_[slot]];
    g.triangles.push_back(tri);
    g.prob.push_back(float(weights[i]));  // normalised below
    g.power += s.materials[s.triangle_material[tri]].emission * (kPi * scene.triangle_area(tri));
  }
  for (LightGroup& g : lights_) {
    double sum = 0;
    for (float w : g.prob) sum += w;
    double acc = 0;
    g.cdf.resize(g.prob.size());
    for (size_t i = 0; i < g.prob.size(); ++i) {
      acc += g.prob[i];
      g.prob[i] = float(g.prob[i] / sum);
      g.cdf[i] = float(acc / sum);
    }
    g.cdf.back() = 1.0f;
  }
}

LightSample LightSampler::MakeSample(uint32_t tri, float u1, float u2, float pdf_select) const {
  const SceneDescription& s = scene_->description();
  const auto& t = s.triangles[tri];
  LightSample ls;
  ls.position = SampleTriangle(s.positions[t[0]], s.positions[t[1]], s.positions[t[2]], u1, u2);
  ls.normal = scene_->triangle_normal(tri);
  ls.radiance = s.materials[s.triangle_material[tri]].emission;
  ls.triangle = tri;
  ls.light = s.triangle_light.empty() ? 0 : s.triangle_light[tri];
  ls.pdf_area = pdf_select / scene_->triangle_area(tri);
  return ls;
}

LightSample LightSampler::SampleLight(size_t light, float u_select, float u1, float u2) const {
  const LightGroup& g = lights_[light];
  const size_t i = std::min<size_t>(std::upper_bound(g.cdf.begin(), g.cdf.end(), u_select) - g.cdf.begin(),
                                    g.cdf.size() - 1);
  return MakeSample(g.triangles[i], u1, u2, g.prob[i]);
}

size_t LightSampler::LightIndex(uint32_t scene_light_id) const {
  const size_t num_ids = light_index_by_id_.empty() ? 0 : light_index_by_id_.size() - 1;
  const size_t slot = (scene_light_id == kNoLight || scene_light_id >= num_ids) ? num_ids : scene_light_id;
  if (slot >= light_index_by_id_.size() || light_index_by_id_[slot] == uint32_t(-1)) return lights_.size();
  return light_index_by_id_[slot];
}

LightSample LightSampler::Sample(float u_select, float u1, float u2) const {
  return EmitterSample(EmitterIndex(u_select), u1, u2);
}

LightSample LightSampler::EmitterSample(size_t emitter, float u1, float u2) const {
  const uint32_t tri = triangles_[emitter];
  return MakeSample(tri, u1, u2, select_prob_by_tri_[tri]);
}

float LightSampler::PdfArea(uint32_t tri) const {
  const float p = select_prob_by_tri_[tri];
  return p > 0.0f ? p / scene_->triangle_area(tri) : 0.0f;
}

}  // namespace pf
