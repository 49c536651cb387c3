#pragma once
// Emitters of a scene: every emissive triangle, chosen with probability ∝ its power
// (Φ = π·A·luminance(Le) for a Lambertian one-sided emitter), then a uniform point on it.
//
// A textured emitter (Material::emission_texture: Le(x) = Le·texel(x)) is chosen ∝ π·A·Le·m,
// m the texture's mean over the triangle estimated by a stratified quadrature
// (MeanEmissionTexel), and its sample's radiance is Le·texel at the sampled point: the
// estimate weighs the choice only, so next-event estimation stays unbiased whatever its error
// (the pdf is the one used, p/A). Photons likewise carry Le·texel(x)·π/(p/A·N) (photon_tracer.cpp):
// their expected total is the exact power. total_power() and light_power() use the estimate.
// Sample's choice ∝ power over every emitter is photon emission's (§2.2: photons per light ∝ its
// power) and the integrator pilot's; next-event estimation chooses a light by LightChoice
// (light_choice.h) and a point on it by SampleLight.
//
// Punctual lights (point, spot, directional: punctual_light.h) are emitters too, numbered after
// the triangles and chosen ∝ their power alike: point 4π·I, spot 2π·I·[(1 − cos θi) +
// (cos θi − cos θo)/3], directional E⊥·π·R² with R the radius of the scene's bounding sphere
// (the disc its photons leave from, photon_tracer.cpp). Their samples are delta samples
// (LightSample::delta()): one position or direction, pdf_area the probability of the choice.
// A scene without them has exactly the emitters, probabilities and light numbers it had before.
//
// The environment (environment_light.h), if the scene has one, is the last emitter and the last
// light, chosen ∝ its power π·R²·∫L dω (R as for a directional light). Its samples are
// directions (LightSample::environment): wi, L(wi), and pdf_area · pdf_direction the density
// per solid angle.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/core/math.h"
#include "common/lights/environment_light.h"

namespace pf {

inline constexpr uint32_t kNotPunctual = std::numeric_limits<uint32_t>::max();

struct LightSample {
  Vec3 position;  // punctual: the light's position (point, spot) in the scene's frame
  Vec3 normal;    // front-face normal of the emitter (emission side); punctual: its direction
  Rgb radiance;   // Le; punctual: I (W/sr) or E⊥ (W/m²)
  uint32_t triangle = 0;
  uint32_t light = 0;
  float pdf_area = 0;                // probability density per unit area (incl. the triangle choice);
                                     // punctual: the probability of choosing the light
  uint32_t punctual = kNotPunctual;  // index into LightSampler::punctual(), or kNotPunctual
  // The environment's sample: position and normal unused, wi the direction towards it, pdf_area
  // the probability of the choice, pdf_direction the solid-angle density of wi.
  bool environment = false;
  Vec3 wi{};
  float pdf_direction = 0;
  bool delta() const { return punctual != kNotPunctual; }
};

// A punctual light as the sampler and the photon tracer use it: in the scene's frame, cosines
// precomputed, its power Φ (RGB, W).
struct PunctualEmitter {
  PunctualLight::Kind kind = PunctualLight::Kind::kPoint;
  Vec3 position;  // point, spot; directional: the centre of the scene's bounding sphere
  Vec3 direction;
  Rgb intensity;                        // I or E⊥
  float cos_inner = 1, cos_outer = -1;  // spot
  float radius = 0;                     // directional: R of the scene's bounding sphere
  Rgb power;
  uint32_t light = 0;
};

// What a delta light sends to a point x: the unit direction towards it, the irradiance on a
// surface facing it (I·falloff/d² or E⊥; black outside a spot's cone) and the distance to it
// (infinite for a directional light).
struct DeltaIncidence {
  Vec3 wi;
  Rgb irradiance;
  float distance = 0;
};

class LightSampler {
 public:
  explicit LightSampler(const EmbreeScene& scene);

  bool empty() const { return triangles_.empty() && punctual_.empty() && !environment_; }
  // Picks an emitter ∝ power with u_select — an emitting triangle, a punctual light or the
  // environment — then a uniform point on the triangle with (u1, u2) (a punctual light's sample
  // is its position or direction, the environment's a direction).
  LightSample Sample(float u_select, float u1, float u2) const;
  // Sample(u_select, u1, u2) in two steps, EmitterSample(EmitterIndex(u_select), u1, u2): which
  // emitter (0 .. num_emitters() − 1: the triangles, then the punctual lights, then the
  // environment) u_select picks,
  // and the sample on it.
  // For callers that keep per emitter what does not depend on the point (the photon tracer).
  size_t EmitterIndex(float u_select) const {
    return std::min<size_t>(std::upper_bound(cdf_.begin(), cdf_.end(), u_select) - cdf_.begin(),
                            cdf_.size() - 1);
  }
  LightSample EmitterSample(size_t emitter, float u1, float u2) const;
  // Total emitted power Σ π·A·Le + Σ Φ of the punctual lights + the environment's (RGB), W.
  const Rgb& total_power() const { return total_power_; }
  size_t num_emitting_triangles() const { return triangles_.size(); }
  // Every emitter EmitterIndex can give: the triangles, then the punctual lights, then the environment.
  size_t num_emitters() const { return triangles_.size() + punctual_.size() + (environment_ ? 1 : 0); }
  const std::vector<PunctualEmitter>& punctual() const { return punctual_; }
  // The environment (null if the scene has none).
  const EnvironmentLight* environment() const { return environment_.get(); }

  // A delta sample's light at x (ls.delta()), and whether nothing blocks the way from x (ng: the
  // geometric normal there, the shadow ray's origin is offset along it) to it.
  DeltaIncidence Incidence(const LightSample& ls, const Vec3& x) const;
  bool Unoccluded(const Vec3& x, const Vec3& ng, const DeltaIncidence& in) const;
  // Whether nothing blocks the way from x along wi to infinity (the environment).
  bool UnoccludedTowards(const Vec3& x, const Vec3& ng, const Vec3& wi) const {
    return Unoccluded(x, ng, DeltaIncidence{wi, Rgb(0.0f), std::numeric_limits<float>::infinity()});
  }

  // Per light (one emitting source primitive, scene.triangle_light), for direct-light
  // estimators that sample each light separately (§4.2.1, §4.2.3). Lights are numbered
  // 0..num_lights()-1 in the order of their first emitting triangle (LightIndex maps a scene
  // light id to its number), triangles without an id form one extra light, and each punctual
  // light is one more, after all of those, and the environment the last.
  size_t num_lights() const { return lights_.size(); }
  const Rgb& light_power(size_t light) const { return lights_[light].power; }
  // Samples light `light` alone: a triangle ∝ power within it, a uniform point on it.
  // pdf_area is the density within that light (1 for a punctual light's delta sample).
  LightSample SampleLight(size_t light, float u_select, float u1, float u2) const;
  // Which light a scene light id is (kNoLight → the extra one); num_lights() if unknown.
  size_t LightIndex(uint32_t scene_light_id) const;
  // The light (0..num_lights()−1) emitting triangle `tri` is part of, and the density per unit
  // area with which SampleLight of that light gives a point on it (0 if it does not emit).
  size_t LightOfTriangle(uint32_t tri) const;
  float PdfAreaWithinLight(uint32_t tri) const;
  // Punctual light `index` (of punctual()) as SampleLight gives it: its delta sample, pdf_area 1.
  LightSample PunctualSample(size_t index) const { return MakePunctualSample(uint32_t(index), 1.0f); }

 private:
  struct LightGroup {
    uint32_t scene_id = 0;
    std::vector<uint32_t> triangles;
    std::vector<float> cdf;
    std::vector<float> prob;  // selection probability within the light, per entry of triangles
    Rgb power;
    uint32_t punctual = kNotPunctual;  // a punctual light's group has no triangles
    bool environment = false;          // nor has the environment's
  };
  LightSample MakeSample(uint32_t tri, float u1, float u2, float pdf_select) const;
  LightSample MakePunctualSample(uint32_t index, float pdf_select) const;
  LightSample MakeEnvironmentSample(float u1, float u2, float pdf_select) const;
  void AddPunctualLights(std::vector<double>* weights);
  void AddEnvironment(std::vector<double>* weights);
  std::vector<LightGroup> lights_;
  std::vector<uint32_t> light_index_by_id_;  // scene id → index in lights_ (kNoLight slot last)

  const EmbreeScene* scene_;
  std::vector<uint32_t> triangles_;                // emissive triangle ids
  std::vector<PunctualEmitter> punctual_;          // emitters num_emitting_triangles() and on
  std::vector<float> punctual_prob_;               // their selection probabilities
  std::unique_ptr<EnvironmentLight> environment_;  // the last emitter, if any
  float environment_prob_ = 0;                     // its selection probability
  std::vector<float> cdf_;                         // cumulative selection probability, last = 1
  std::vector<float> select_prob_by_tri_;          // per scene triangle; 0 for non-emitters
  std::vector<float> within_prob_by_tri_;          // the same within the triangle's light
  Rgb total_power_;
};

// Uniform point on a triangle from two uniforms (barycentric square-root mapping).
inline Vec3 SampleTriangle(const Vec3& a, const Vec3& b, const Vec3& c, float u1, float u2) {
  const float su = std::sqrt(u1);
  // On the triangle's plane to ½ ulp at any magnitude of the coordinates (ray.h).
  return InterpolateOnTriangle(a, b, c, double(su) * (1.0 - double(u2)), double(su) * double(u2));
}

// The texture coordinates of SampleTriangle's point for (u1, u2) on a triangle whose vertices
// have coordinates a, b, c (the same barycentrics).
inline TextureCoordinates UvOnTriangle(const TextureCoordinates& a, const TextureCoordinates& b,
                                       const TextureCoordinates& c, float u1, float u2) {
  const float su = std::sqrt(u1);
  const double b1 = double(su) * (1.0 - double(u2)), b2 = double(su) * double(u2);
  return {float(a[0] + b1 * (double(b[0]) - a[0]) + b2 * (double(c[0]) - a[0])),
          float(a[1] + b1 * (double(b[1]) - a[1]) + b2 * (double(c[1]) - a[1]))};
}

// The mean of `texture` over the triangle with texture coordinates a, b, c (area-weighted),
// by a stratified quadrature of SampleTriangle's points: from 4² points up to 64², about four
// per texel the triangle covers.
Rgb MeanEmissionTexel(const Texture& texture, const TextureCoordinates& a, const TextureCoordinates& b,
                      const TextureCoordinates& c);

}  // namespace pf
