#pragma once
// What `integrator auto` (the default of pf render and pf submit) becomes for a scene and camera,
// and why (docs/renderer.md, "Choosing the integrator"; measured in docs/results/time-budget.md).
// Decided once, where the scene is loaded (pf), from the scene's materials and two pilots — camera
// and shadow rays (light_reach.h), and with mirrors or glass, photons (caustic_reach.h) — so the job stores a
// concrete integrator and every worker renders the same one. Each part can be forced: --integrator
// path|photonmap, --set occlusion-test=....

#include <vector>

#include "common/render/caustic_reach.h"
#include "common/render/job_render_settings.h"
#include "common/render/light_reach.h"

namespace pf {

// Below this lit fraction the scene is taken as lit through openings: the photon map, with the
// occlusion test (Wald 1999, §4.1.1) against light bleeding through the walls between the lit and
// the unlit parts.
inline constexpr double kIndirectlyLitBelow = 0.5;
// With mirrors or glass, the photon map is chosen for their caustics when a path tracer cannot
// render them: above this share of the light landing on diffuse surfaces coming from a punctual
// light through a mirror or glass (CausticReach::punctual_caustic_share), which it never finds,
inline constexpr double kPunctualCausticsAbove = 0.01;
// or above this squared relative noise per sample from the caustics it finds by chance
// (CausticReach::relative_caustic_variance): small lamps seen through glass.
inline constexpr double kNoisyCausticsAbove = 0.5;
// Above this leak fraction (LightReach::leak_fraction) a photon map gets the occlusion test.
inline constexpr double kLeakyAbove = 0.01;

struct IntegratorEvidence {
  bool photon_map_settings_given = false;  // the user set a setting only the photon map reads
  bool occlusion_test_given = false;       // the user set occlusion-test either way
  bool specular_surfaces = false;          // SceneHasSpecularSurfaces
  int lights = 0;                          // SceneDescription::num_lights (for the reason)
  LightReach reach;                        // MeasureLightReach with the job's camera
  CausticReach caustics;                   // MeasureCausticReach with the job's camera, if specular
};

struct IntegratorChoice {
  IntegratorKind integrator = IntegratorKind::kPath;
  bool occlusion_test = false;      // turn the occlusion test on (only if not given)
  std::vector<AutoChoice> choices;  // "integrator", and "occlusion-test" when it is turned on
};

// A perfect mirror or glass (a delta lobe, bsdf.h) on some material: light reflected or refracted
// onto a diffuse surface there (L S+ D, a caustic) is reached by no shadow ray.
bool SceneHasSpecularSurfaces(const SceneDescription& scene);

// What the scene and its camera tell (the user's part of the evidence is the caller's): its
// materials, its lights and the pilots (MeasureLightReach; MeasureCausticReach if specular). The pilot's leak
// distance is the first progressive pass's radius (progressive_radius.h) for the larger of the radii of
// `settings` (photons, k, progressive-radius as the job has them) and of the default photons and k, so that
// the guard errs towards the occlusion test.
IntegratorEvidence SceneEvidence(const SceneDescription& scene, const CameraSpec& camera,
                                 const JobRenderSettings& settings);

// The rule, in order: photon-map settings given → the photon map; specular surfaces whose caustics
// a path tracer misses (kPunctualCausticsAbove) or finds only noisily (kNoisyCausticsAbove), or that
// the camera sees no diffuse surface past, → the photon map; a lit fraction below kIndirectlyLitBelow → the
// photon map; else the path tracer (unbiased, and as good where most of what is seen sees a light: many
// lights alone do not make the photon map the better choice, CONFERENCE in docs/results/time-budget.md). A
// photon map chosen here gets the occlusion test when the leak fraction is above kLeakyAbove.
IntegratorChoice ChooseIntegrator(const IntegratorEvidence& evidence);

}  // namespace pf
