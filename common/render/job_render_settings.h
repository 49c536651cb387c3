#pragma once
// Everything about *how* a job renders that is the same for all its tasks, and how its `auto`
// settings become concrete for a scene. Every field is a row of the settings table
// (render_settings_table.h: name, type, default, range, help, whether it changes a photon map);
// adding a setting = a field here + a row there + a field of farm.proto's PhotonMapSettings or
// RenderSettings (docs/settings.md).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "common/photon/photon_maps.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/progressive_radius.h"
#include "common/sampling/sampler.h"
#include "common/scene/scene.h"

namespace pf {

enum class IntegratorKind { kPath, kPhotonMap };

// Who traces a farm job's photon maps (docs/farm.md "Photon maps traced once"). Never
// changes the image: a map traced in pieces and built once is the map a worker builds alone.
enum class MapTracingMode {
  kAuto,         // distributed for kd-tree maps that more than one render task uses, else local
  kLocal,        // every worker traces and builds the maps of its tasks
  kDistributed,  // kd-tree maps: pieces traced by any worker, built once by the coordinator
};

// What an `auto` setting became for a scene, and why (logged by pf and pf-worker).
struct AutoChoice {
  std::string setting, value, reason;
};

// Direct light `auto`: PhotonDirect from this many lights on, Monte Carlo below (docs/renderer.md,
// "auto settings"; measured in docs/results/estimators.md).
inline constexpr int kPhotonDirectMinLights = 8;

// What the `auto` settings depend on in a scene (JobRenderSettings::Resolved), and nothing
// else: known from the scene itself, or from what the coordinator recorded of it at upload, so
// the coordinator resolves a job once, at submission, without loading the scene.
struct SceneTraits {
  bool caustic_paths = false;  // specular or glossy surfaces (SceneNeedsCausticMap)
  int lights = 0;
};
SceneTraits TraitsOf(const SceneDescription& scene);

// Everything about *how* to render that is the same for all tasks of a job.
struct JobRenderSettings {
  IntegratorKind integrator = IntegratorKind::kPhotonMap;
  // Pixel samples and photons (docs/renderer.md, "Sampling and determinism"): Owen-scrambled Sobol by
  // default.
  SamplerKind sampler = SamplerKind::kSobol;
  uint64_t photons = 200000;
  PhotonMapKind structure = PhotonMapKind::kKdTree;
  // Widest extent: 2-4x faster queries than level % 3 in rooms with axis-aligned walls
  // (bench/photon_map_bench; the thesis suggests it for flat scenes, §2.3 footnote 2).
  KdSplitRule kd_split = KdSplitRule::kWidestExtent;
  CausticMapMode caustic = CausticMapMode::kAuto;
  int k = 100;
  float caustic_radius = 0.0f;  // 0 = DefaultCausticOptions
  int glossy_depth = 1;
  FeasibilityTest direction_test = FeasibilityTest::kInQuery;
  // Chapter 4 (see photon_map_integrator.h and direct_light.h).
  std::optional<DirectLightMode> direct;  // nullopt = auto (see Resolved)
  int shadow_rays = 16;                   // MC: per shading point; PhotonDirect: N_total
  float light_uniform_fraction = 0.0f;    // MC: defensive mixing β
  int photon_direct_k = 50;
  NonContributingMode non_contributing = NonContributingMode::kOneRandom;
  float photon_direct_cache = 0.25f;                           // neighbour-set cache radius fraction; 0 = off
  int local_pass_rays = 0;                                     // §4.3; 0 = off
  LocalPassLookup local_pass_lookup = LocalPassLookup::kFull;  // precomputed irradiance (Christensen 1999)
  bool site_occlusion_test = true;  // precomputed sites drop photons of unseen origin (§4.1.1)
  float irradiance_cache_error =
      0.0f;                     // local pass: irradiance caching, Ward's a (irradiance_cache.h); 0 = off
  bool occlusion_test = false;  // §4.1.1
  int adaptive_k_min = 0;       // §4.8; 0 = off
  // Farm only (docs/farm.md, "Photon maps traced once"); pf render --local-only traces in-process.
  MapTracingMode map_tracing = MapTracingMode::kAuto;
  // Importance-driven photon maps (§4.7; common/photon/importance_map.h). `auto` is decided per
  // map by a pilot with fixed seeds (the same for every map of a job) and logged.
  ImportanceMode importance = ImportanceMode::kOff;
  float importance_min_probability = 0.05f;  // p_min
  float importance_strength = 4.0f;          // s
  uint64_t importons = 0;                    // 0 = one per pixel
  // Caustic splitting (Wald 1999, §4.6; photon_tracer.h): S× the caustic photons; 1 = off.
  uint32_t caustic_split = 1;
  CausticSplitMethod caustic_split_method = CausticSplitMethod::kBrute;
  // The progressive plan (plan_factory.h; progressive_radius.h, Knaus & Zwicker 2011): the
  // schedule's α and the first pass's radius (0 = derived from the scene and the photons per pass).
  // Read only by a progressive plan's tasks; they change no map (the radius is a query setting).
  double progressive_alpha = kDefaultProgressiveAlpha;
  float progressive_radius = 0.0f;

  // The settings with every `auto` made concrete for `scene`: a pure function of both, so every
  // worker and `pf render` decide alike. `choices` (optional) receives each decision and its reason.
  // Idempotent: resolved settings resolve to themselves.
  JobRenderSettings Resolved(const SceneDescription& scene, std::vector<AutoChoice>* choices = nullptr) const;
  JobRenderSettings Resolved(const SceneTraits& scene, std::vector<AutoChoice>* choices = nullptr) const;

  // The integrator options these settings describe, for a scene with these bounds. Requires
  // resolved settings (std::logic_error otherwise).
  PhotonMapIntegratorOptions IntegratorOptions(const Bounds3& scene_bounds) const;
  // The photon-map options (everything but the seed and threads).
  PhotonMapsOptions MapsOptions() const;

  // Stable text form of the settings that change a photon map (cache key): the table's
  // changes-map rows that apply (render_settings_table.h, MapFingerprintOf). Requires resolved
  // settings.
  std::string MapFingerprint() const;
};

}  // namespace pf
