#include "common/render/integrator_choice.h"

#include <fmt/format.h>

#include <algorithm>

#include "common/camera/camera.h"
#include "common/materials/bsdf.h"
#include "common/render/progressive_radius.h"
#include "common/render/scene_runtime.h"

namespace pf {

bool SceneHasSpecularSurfaces(const SceneDescription& scene) {
  const Vec3 n(0.0f, 0.0f, 1.0f);
  for (const Material& m : scene.materials)
    if (Bsdf(m, n, n).HasLobes(kLobeSpecularReflection | kLobeSpecularTransmission)) return true;
  return false;
}

IntegratorEvidence SceneEvidence(const SceneDescription& scene, const CameraSpec& camera,
                                 const JobRenderSettings& settings) {
  IntegratorEvidence e;
  e.specular_surfaces = SceneHasSpecularSurfaces(scene);
  e.lights = int(scene.num_lights);
  const SceneRuntime runtime(scene);
  const JobRenderSettings defaults;
  const Bounds3& bounds = runtime.accel.bounds();
  const double radius = std::max({DerivedInitialRadius(bounds, defaults.photons, defaults.k),
                                  DerivedInitialRadius(bounds, settings.photons, settings.k),
                                  double(settings.progressive_radius)});
  const Camera pilot_camera(camera, scene.origin);
  e.reach = MeasureLightReach(runtime, pilot_camera, float(radius));
  if (e.specular_surfaces) e.caustics = MeasureCausticReach(runtime, pilot_camera);
  return e;
}

IntegratorChoice ChooseIntegrator(const IntegratorEvidence& e) {
  IntegratorChoice c;
  const std::string seen = fmt::format(
      "{:.0f}% of the {} surface points the camera sees are lit directly, {:.1f}% unlit next to lit space "
      "behind a thin wall",
      100.0 * e.reach.lit_fraction, e.reach.points, 100.0 * e.reach.leak_fraction);
  const std::string caustics = fmt::format(
      "{:.1f}% of the light landing on diffuse surfaces comes from point, spot or directional lights "
      "by way of them, the caustics are {:.1f}% of the irradiance the camera sees and add a squared "
      "relative noise of {:.2f} per path-traced sample",
      100.0 * e.caustics.punctual_caustic_share, 100.0 * e.caustics.caustic_fraction,
      e.caustics.relative_caustic_variance);
  const bool missed = e.caustics.punctual_caustic_share > kPunctualCausticsAbove;
  const bool noisy = e.caustics.relative_caustic_variance > kNoisyCausticsAbove;
  const auto choose = [&c](IntegratorKind kind, std::string reason) {
    c.integrator = kind;
    c.choices.push_back(
        {"integrator", kind == IntegratorKind::kPath ? "path" : "photonmap", std::move(reason)});
  };
  if (e.photon_map_settings_given) {
    choose(IntegratorKind::kPhotonMap, "settings only the photon map reads were given; " + seen);
  } else if (e.specular_surfaces && (missed || noisy || e.caustics.points == 0)) {
    const std::string why = e.caustics.points == 0
                                ? "the camera sees no diffuse surface, so the caustic pilot has no evidence"
                            : missed ? fmt::format("{} (> {:.0f}%: light a path tracer never finds)",
                                                   caustics, 100.0 * kPunctualCausticsAbove)
                                     : fmt::format("{} (> {:.1f}: light a path tracer finds by chance)",
                                                   caustics, kNoisyCausticsAbove);
    choose(IntegratorKind::kPhotonMap,
           "mirror or glass surfaces: " + why +
               "; photons carry the light they reflect or refract onto diffuse surfaces (caustics, "
               "Wald 1999, 2.2); " +
               seen);
  } else if (e.reach.points > 0 && e.reach.lit_fraction < kIndirectlyLitBelow) {
    choose(
        IntegratorKind::kPhotonMap,
        seen + fmt::format(" (< {:.0f}%): the rest is lit through openings, which paths find by chance and "
                           "photons along the way light goes",
                           100.0 * kIndirectlyLitBelow));
  } else {
    const std::string specular =
        e.specular_surfaces
            ? fmt::format(
                  "; mirror or glass surfaces, but {} (at most {:.0f}% and {:.1f}: a path tracer "
                  "renders their caustics)",
                  caustics, 100.0 * kPunctualCausticsAbove, kNoisyCausticsAbove)
            : ", no mirror or glass";
    choose(IntegratorKind::kPath,
           seen + specular +
               fmt::format(", {} light{}: shadow rays find the light (unbiased, no photon map)", e.lights,
                           e.lights == 1 ? "" : "s"));
    return c;
  }
  if (e.reach.leak_fraction > kLeakyAbove && !e.occlusion_test_given) {
    c.occlusion_test = true;
    c.choices.push_back(
        {"occlusion-test", "true",
         fmt::format("{:.1f}% of the points the camera sees are unlit, with lit space behind a wall "
                     "within the photon search radius (> {:.0f}%): photons whose "
                     "incoming path the point cannot see are dropped (no light bleeding, 4.1.1)",
                     100.0 * e.reach.leak_fraction, 100.0 * kLeakyAbove)});
  }
  return c;
}

}  // namespace pf
