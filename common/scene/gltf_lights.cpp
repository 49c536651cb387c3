// KHR_lights_punctual → PunctualLight (gltf_lights.h).
#include "common/scene/gltf_lights.h"

#include <tiny_gltf.h>

#include <cmath>

#include "common/core/error.h"

namespace pf {

bool MapGltfLight(const tinygltf::Light& g, size_t index, const mgf::Affine& world, const std::string& file,
                  std::vector<std::string>* warnings, PunctualLight* out) {
  using Kind = PunctualLight::Kind;
  const std::string where = "KHR_lights_punctual.lights[" + std::to_string(index) + "]";
  auto fail = [&](const std::string& why) { throw InputError(SourceLocation{file, 0}, where + ": " + why); };
  PunctualLight l;
  l.name = g.name.empty() ? where : g.name;
  if (g.type == "point") {
    l.kind = Kind::kPoint;
  } else if (g.type == "spot") {
    l.kind = Kind::kSpot;
  } else if (g.type == "directional") {
    l.kind = Kind::kDirectional;
  } else {
    fail("type '" + g.type + "' is not one of point, spot, directional");
  }
  if (!(g.intensity >= 0.0) || !std::isfinite(g.intensity)) fail("intensity must be a finite number >= 0");
  double rgb[3] = {1, 1, 1};
  if (g.color.size() == 3)
    for (int c = 0; c < 3; ++c) rgb[c] = g.color[size_t(c)];
  for (double& c : rgb) {
    if (!(c >= 0.0)) fail("color must be 3 numbers >= 0");
    c *= g.intensity / kLumensPerWatt;
    if (!(c <= double(kMaxLightIntensity)))
      fail("color x intensity / 683 exceeds " + std::to_string(kMaxLightIntensity) + " in a channel");
  }
  l.intensity = Rgb(float(rgb[0]), float(rgb[1]), float(rgb[2]));
  if (l.intensity.IsBlack()) {
    warnings->push_back(file + ": " + where + ": emits nothing (color x intensity is 0); ignored");
    return false;
  }
  if (g.range > 0.0)
    warnings->push_back(file + ": " + where + ": range " + std::to_string(g.range) +
                        " is ignored (pf's lights fall off as 1/d^2 without a cut-off)");
  l.position = world.t;
  const Vec3d axis = world.Vector(Vec3d(0, 0, -1));
  const double length = Length(axis);
  if (l.kind != Kind::kPoint) {
    if (!(length > 0.0) || !std::isfinite(length)) fail("its node's transform has no direction (scale 0?)");
    l.direction = Vec3(axis / length);
  }
  if (l.kind == Kind::kSpot) {
    const double inner = g.spot.innerConeAngle, outer = g.spot.outerConeAngle;
    const double half_pi = std::acos(0.0);
    // The specification asks for innerConeAngle < outerConeAngle, but Blender's exporter writes
    // them equal for a spot lamp without blend: read as a hard-edged cone, not refused.
    if (!(inner >= 0.0 && inner <= outer && outer > 0.0 && outer <= half_pi))
      fail(
          "spot cone angles must satisfy 0 <= innerConeAngle <= outerConeAngle <= pi/2, outerConeAngle > 0 "
          "(radians)");
    l.inner_cone_deg = float(inner * 90.0 / half_pi);
    l.outer_cone_deg = float(outer * 90.0 / half_pi);
    // Below the manifest's band the cone's float cosine rounds to 1: a spot of no power.
    if (!(l.outer_cone_deg >= kMinSpotFalloffDeg))
      fail("outerConeAngle must be at least " + std::to_string(kMinSpotFalloffDeg) + " degrees");
    // A falloff band narrower than the manifest's limit is a hard edge too: SpotFalloff and the
    // photon emitter's cone sampling need no band then (punctual_light.h, photon_tracer.cpp).
    if (l.outer_cone_deg < l.inner_cone_deg + kMinSpotFalloffDeg) l.inner_cone_deg = l.outer_cone_deg;
  }
  *out = l;
  return true;
}

}  // namespace pf
