#include "common/lights/light_sampler.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "common/core/error.h"

namespace pf {

Rgb MeanEmissionTexel(const Texture& texture, const TextureCoordinates& a, const TextureCoordinates& b,
                      const TextureCoordinates& c) {
  // Texels covered: the triangle's area in texture space times the image's texel count.
  const double area = 0.5 * std::abs((double(b[0]) - a[0]) * (double(c[1]) - a[1]) -
                                     (double(c[0]) - a[0]) * (double(b[1]) - a[1]));
  const double texels = area * texture.image->width() * texture.image->height();
  const int side =
      int(std::clamp(std::ceil(2.0 * std::sqrt(std::isfinite(texels) ? texels : 0.0)), 4.0, 64.0));
  Rgb sum(0.0f);
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j)
      sum += texture.Lookup(
          UvOnTriangle(a, b, c, (float(i) + 0.5f) / float(side), (float(j) + 0.5f) / float(side)));
  return sum * (1.0f / float(side * side));
}

LightSampler::LightSampler(const EmbreeScene& scene) : scene_(&scene) {
  const SceneDescription& s = scene.description();
  select_prob_by_tri_.assign(s.triangles.size(), 0.0f);
  std::vector<double> weights;
  std::vector<Rgb> emission;  // per entry of triangles_: Le, times the texture's mean if textured
  for (uint32_t t = 0; t < s.triangles.size(); ++t) {
    const Material& m = s.materials[s.triangle_material[t]];
    if (!m.IsEmissive()) continue;
    const float area = scene.triangle_area(t);
    if (!(area > 0.0f)) continue;
    Rgb le = m.emission;
    if (m.emission_texture >= 0 && !s.uvs.empty()) {
      const auto& tri = s.triangles[t];
      le = le * MeanEmissionTexel(s.textures[size_t(m.emission_texture)], s.uvs[tri[0]], s.uvs[tri[1]],
                                  s.uvs[tri[2]]);
    }
    // The floor keeps a textured triangle whose estimate is black selectable (unbiased).
    const double w = double(kPi) * area * std::max(le.Luminance(), 1e-6f * m.emission.Max());
    if (!(w > 0.0)) continue;
    triangles_.push_back(t);
    weights.push_back(w);
    emission.push_back(le);
    total_power_ += le * (kPi * area);
  }
  AddPunctualLights(&weights);
  AddEnvironment(&weights);
  double total = 0;
  for (double w : weights) total += w;
  cdf_.resize(weights.size());
  double acc = 0;
  for (size_t i = 0; i < weights.size(); ++i) {
    acc += weights[i];
    cdf_[i] = float(acc / total);
    if (i < triangles_.size()) {
      select_prob_by_tri_[triangles_[i]] = float(weights[i] / total);
    } else if (i < triangles_.size() + punctual_.size()) {
      punctual_prob_.push_back(float(weights[i] / total));
    } else {
      environment_prob_ = float(weights[i] / total);
    }
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
      lights_.push_back(LightGroup{id, {}, {}, {}, Rgb(0.0f), kNotPunctual});
    }
    LightGroup& g = lights_[light_index_by_id_[slot]];
    g.triangles.push_back(tri);
    g.prob.push_back(float(weights[i]));  // normalised below
    g.power += emission[i] * (kPi * scene.triangle_area(tri));
  }
  within_prob_by_tri_.assign(s.triangles.size(), 0.0f);
  for (LightGroup& g : lights_) {
    if (g.triangles.empty()) continue;
    double sum = 0;
    for (float w : g.prob) sum += w;
    double acc = 0;
    g.cdf.resize(g.prob.size());
    for (size_t i = 0; i < g.prob.size(); ++i) {
      acc += g.prob[i];
      g.prob[i] = float(g.prob[i] / sum);
      g.cdf[i] = float(acc / sum);
      within_prob_by_tri_[g.triangles[i]] = g.prob[i];
    }
    g.cdf.back() = 1.0f;
  }
  // Each punctual light is a light of its own, after those of the triangles (its id is one of
  // the scene's 0..num_lights-1, given by the loader after the emitting primitives'). An id out of
  // that range would take the slot of the triangles without an id: a scene built wrongly.
  const auto own_slot = [num_ids](uint32_t id, const char* what) {
    if (id >= num_ids)
      throw std::logic_error(std::string("light sampler: ") + what + " has light id " + std::to_string(id) +
                             ", not below the scene's num_lights " + std::to_string(num_ids));
    return size_t(id);
  };
  for (size_t k = 0; k < punctual_.size(); ++k) {
    const uint32_t id = punctual_[k].light;
    light_index_by_id_[own_slot(id, "a punctual light")] = uint32_t(lights_.size());
    lights_.push_back(LightGroup{id, {}, {}, {}, punctual_[k].power, uint32_t(k)});
  }
  if (environment_) {
    const uint32_t id = environment_->light();
    light_index_by_id_[own_slot(id, "the environment")] = uint32_t(lights_.size());
    lights_.push_back(LightGroup{id, {}, {}, {}, environment_->power(), kNotPunctual, true});
  }
}

void LightSampler::AddEnvironment(std::vector<double>* weights) {
  const SceneDescription& s = scene_->description();
  if (!s.environment) return;
  const Bounds3& bounds = scene_->bounds();
  const Vec3 centre = bounds.Empty() ? Vec3(0.0f) : bounds.Center();
  const float radius = bounds.Empty() ? 0.0f : 0.5f * Length(bounds.Diagonal());
  environment_ = std::make_unique<EnvironmentLight>(*s.environment, centre, radius);
  const Rgb& power = environment_->power();
  const double w = double(std::max(power.Luminance(), 1e-6f * power.Max()));
  // Never dropped in silence: the scene counted it as a light (the loader's no-light check).
  if (!(w > 0.0))
    throw InputError("environment: its power is not a finite positive number (a scene of radius " +
                     std::to_string(radius) + ")");
  weights->push_back(w);
  total_power_ += power;
}

LightSample LightSampler::MakeEnvironmentSample(float u1, float u2, float pdf_select) const {
  const EnvironmentLight::DirectionSample d = environment_->Sample(u1, u2);
  LightSample ls;
  ls.radiance = d.radiance;
  ls.light = environment_->light();
  ls.pdf_area = pdf_select;
  ls.environment = true;
  ls.wi = d.wi;
  ls.pdf_direction = d.pdf;
  return ls;
}

void LightSampler::AddPunctualLights(std::vector<double>* weights) {
  const SceneDescription& s = scene_->description();
  const Bounds3& bounds = scene_->bounds();
  const Vec3 centre = bounds.Empty() ? Vec3(0.0f) : bounds.Center();
  const float radius = bounds.Empty() ? 0.0f : 0.5f * Length(bounds.Diagonal());
  for (const PunctualLight& l : s.punctual_lights) {
    PunctualEmitter e;
    e.kind = l.kind;
    e.position = Vec3(l.position - s.origin);  // into the scene's frame (scene_frame.h), in double
    e.direction = Normalize(l.direction);
    e.intensity = l.intensity;
    e.light = l.light;
    switch (l.kind) {
      case PunctualLight::Kind::kPoint:
        e.power = l.intensity * (4.0f * kPi);
        break;
      case PunctualLight::Kind::kSpot: {
        e.cos_inner = std::cos(l.inner_cone_deg * kPi / 180.0f);
        e.cos_outer = std::cos(l.outer_cone_deg * kPi / 180.0f);
        // ∫ falloff dω over the cone: the flat inner cap plus the squared ramp (its mean is 1/3).
        e.power = l.intensity * (2.0f * kPi * ((1.0f - e.cos_inner) + (e.cos_inner - e.cos_outer) / 3.0f));
        break;
      }
      case PunctualLight::Kind::kDirectional:
        // E⊥ through the disc of the bounding sphere's radius: every ray that can hit the scene.
        e.position = centre;
        e.radius = radius;
        e.power = l.intensity * (kPi * radius * radius);
        break;
    }
    const double w = double(std::max(e.power.Luminance(), 1e-6f * e.power.Max()));
    // Never dropped in silence: the scene counted it as a light (the loader's no-light check).
    if (!(w > 0.0) || !e.power.IsFinite())
      throw InputError("light '" + l.name + "': its power is not a finite positive number (intensity " +
                       std::to_string(l.intensity.Max()) + "; a directional light over a scene of radius " +
                       std::to_string(radius) + ")");
    punctual_.push_back(e);
    weights->push_back(w);
    total_power_ += e.power;
  }
}

LightSample LightSampler::MakePunctualSample(uint32_t index, float pdf_select) const {
  const PunctualEmitter& e = punctual_[index];
  return LightSample{.position = e.position,
                     .normal = e.direction,
                     .radiance = e.intensity,
                     .light = e.light,
                     .pdf_area = pdf_select,
                     .punctual = index};
}

DeltaIncidence LightSampler::Incidence(const LightSample& ls, const Vec3& x) const {
  const PunctualEmitter& e = punctual_[ls.punctual];
  DeltaIncidence in;
  if (e.kind == PunctualLight::Kind::kDirectional) {
    in.wi = -e.direction;
    in.irradiance = e.intensity;
    in.distance = std::numeric_limits<float>::infinity();
    return in;
  }
  const Vec3 d = e.position - x;
  const float dist2 = LengthSquared(d);
  if (!(dist2 > 0.0f)) return in;  // at the light itself: nothing defined, nothing sent
  in.distance = std::sqrt(dist2);
  in.wi = d / in.distance;
  const float falloff = e.kind == PunctualLight::Kind::kSpot
                            ? SpotFalloff(-Dot(in.wi, e.direction), e.cos_inner, e.cos_outer)
                            : 1.0f;
  in.irradiance = e.intensity * (falloff / dist2);
  return in;
}

bool LightSampler::Unoccluded(const Vec3& x, const Vec3& ng, const DeltaIncidence& in) const {
  const Vec3 origin = OffsetRayOrigin(x, Dot(in.wi, ng) >= 0.0f ? ng : -ng, scene_->epsilon());
  return !scene_->Occluded(Ray{origin, in.wi, in.distance});
}

LightSample LightSampler::MakeSample(uint32_t tri, float u1, float u2, float pdf_select) const {
  const SceneDescription& s = scene_->description();
  const auto& t = s.triangles[tri];
  LightSample ls;
  ls.position = SampleTriangle(s.positions[t[0]], s.positions[t[1]], s.positions[t[2]], u1, u2);
  ls.normal = scene_->triangle_normal(tri);
  const Material& m = s.materials[s.triangle_material[tri]];
  ls.radiance = m.emission;
  if (m.emission_texture >= 0 && !s.uvs.empty())
    ls.radiance = ls.radiance * s.textures[size_t(m.emission_texture)].Lookup(
                                    UvOnTriangle(s.uvs[t[0]], s.uvs[t[1]], s.uvs[t[2]], u1, u2));
  ls.triangle = tri;
  ls.light = s.triangle_light.empty() ? 0 : s.triangle_light[tri];
  ls.pdf_area = pdf_select / scene_->triangle_area(tri);
  return ls;
}

LightSample LightSampler::SampleLight(size_t light, float u_select, float u1, float u2) const {
  const LightGroup& g = lights_[light];
  if (g.punctual != kNotPunctual) return MakePunctualSample(g.punctual, 1.0f);
  if (g.environment) return MakeEnvironmentSample(u1, u2, 1.0f);
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
  if (emitter >= triangles_.size() + punctual_.size())
    return MakeEnvironmentSample(u1, u2, environment_prob_);
  if (emitter >= triangles_.size()) {
    const size_t k = emitter - triangles_.size();
    return MakePunctualSample(uint32_t(k), punctual_prob_[k]);
  }
  const uint32_t tri = triangles_[emitter];
  return MakeSample(tri, u1, u2, select_prob_by_tri_[tri]);
}

size_t LightSampler::LightOfTriangle(uint32_t tri) const {
  const SceneDescription& s = scene_->description();
  return LightIndex(s.triangle_light.empty() ? kNoLight : s.triangle_light[tri]);
}

float LightSampler::PdfAreaWithinLight(uint32_t tri) const {
  const float p = within_prob_by_tri_[tri];
  return p > 0.0f ? p / scene_->triangle_area(tri) : 0.0f;
}

}  // namespace pf
