#pragma once
// Punctual lights: point, spot and directional (docs/scene-manifest.md, "lights";
// docs/renderer.md, "Punctual lights"). Delta lights: no surface, never hit by a ray, reached
// only by next-event estimation and by the photons they emit.
//
// Units are radiometric and the conventions those of glTF 2.0's KHR_lights_punctual, so that a
// glTF loader maps its lights one to one (a photometric glTF value divides by 683 lm/W):
//   point        radiant intensity I (W/sr, RGB) in every direction; Φ = 4π·I.
//   spot         I·falloff(θ) about `direction`, θ the angle from the axis; glTF's smooth
//                falloff: t = clamp((cos θ − cos θo)/(cos θi − cos θo), 0, 1), falloff = t²;
//                Φ = 2π·I·[(1 − cos θi) + (cos θi − cos θo)/3] (the integral of that falloff).
//   directional  irradiance E⊥ (W/m², RGB) on a surface facing the light, travelling along
//                `direction` from outside the scene.
// `intensity` holds I or E⊥ (glTF's color × intensity).

#include <cstdint>
#include <string>

#include "common/core/math.h"

namespace pf {

// Limits a scene's lights must keep (checked where they are read, the manifest): the largest
// channel of I or E⊥, so that every power stays a finite float, and the narrowest spot falloff
// band (outer − inner half-angle), so that the float cosines of the two angles differ. A glTF
// spot with a narrower band is read as a hard edge (inner = outer: equal cosines, no band, which
// SpotFalloff and the photon emitter handle without dividing by it).
inline constexpr float kMaxLightIntensity = 1e20f;
inline constexpr float kMinSpotFalloffDeg = 0.1f;

struct PunctualLight {
  enum class Kind : uint8_t { kPoint, kSpot, kDirectional };
  Kind kind = Kind::kPoint;
  std::string name{};
  Vec3d position{};           // world coordinates, like cameras (point, spot)
  Vec3 direction{0, -1, 0};   // unit; the direction the light travels (spot axis, directional)
  Rgb intensity{};            // I (W/sr) for point and spot, E⊥ (W/m²) for directional
  float inner_cone_deg = 0;   // spot: half-angle of full intensity (glTF innerConeAngle)
  float outer_cone_deg = 45;  // spot: half-angle where it reaches 0 (glTF outerConeAngle)
  uint32_t light = 0;         // the scene light id (scene.h: photons carry it, §4.2.3)
};

// The spot falloff above from cos θ and the cone's cosines (1 inside the inner cone).
inline float SpotFalloff(float cos_theta, float cos_inner, float cos_outer) {
  if (cos_theta >= cos_inner) return 1.0f;
  if (cos_theta <= cos_outer) return 0.0f;
  const float t = (cos_theta - cos_outer) / (cos_inner - cos_outer);
  return t * t;
}

}  // namespace pf
