#pragma once
// The integrators by name (the `integrator` setting, docs/settings.md): a registry of builders
// in the manner of pbrt-v4's Integrator::Create(name, parameters, ...) and Mitsuba's plugins.
// Each entry says which settings it reads — the table's rows of its groups (render_setting.h,
// SettingGroup: the table says what a setting belongs to, the entry which groups an integrator
// reads) — and its builder checks those settings before it builds. UnusedSettings
// (render_settings_rules.h) and the EXR header ask the entry whether a setting applies, so the
// answer has one source. The names are the `integrator` setting's choices; a test checks that
// both list the same (tests/common/integrator_factory_test.cpp).

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/core/named_registry.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon_maps.h"
#include "common/render/integrator.h"
#include "common/render/job_render_settings.h"
#include "common/render/radiance_part.h"
#include "common/render/render_setting.h"

namespace pf {

// What an integrator renders with besides its settings.
struct IntegratorInputs {
  const EmbreeScene* scene = nullptr;
  const LightSampler* lights = nullptr;
  // The maps built from the resolved settings' MapsOptions, for an integrator that
  // UsesPhotonMaps(); they outlive the integrator.
  const PhotonMaps* maps = nullptr;
  int threads = 1;  // for work done once before the pixels (precomputed irradiance, §4.3)
  RadiancePart part = RadiancePart::kAll;
  // > 0: a progressive pass (render/progressive_radius.h): every map estimate sums the photons
  // within this radius (RadianceEstimateOptions::radius_query) instead of the k nearest.
  float pass_radius = 0.0f;
};

struct IntegratorEntry {
  std::string_view name = {};  // the `integrator` setting's choice: "path"
  IntegratorKind kind = IntegratorKind::kPath;
  std::string_view title = {};  // in messages: "the path tracer"
  // The groups of table rows it reads (SettingGroup).
  std::vector<SettingGroup> groups = {};
  // An integrator for resolved settings (JobRenderSettings::Resolved). InputError naming the
  // first setting it reads that is out of range or contradicts another.
  std::function<std::unique_ptr<Integrator>(const JobRenderSettings&, const IntegratorInputs&)> build =
      nullptr;

  // Whether it reads the setting of `row` (its group is one of `groups`).
  bool Reads(const RenderSetting& row) const;
  // Whether it needs photon maps (it reads the kPhotonMap group): the caller builds or fetches
  // them from the settings' MapsOptions and passes them in IntegratorInputs::maps.
  bool UsesPhotonMaps() const;
};

// Every integrator, in the order of the `integrator` setting's choices.
const NamedRegistry<IntegratorEntry>& Integrators();

// The integrator called `name` (InputError listing the known names if there is none), built from
// `settings` (resolved) and `inputs`.
std::unique_ptr<Integrator> MakeIntegrator(std::string_view name, const JobRenderSettings& settings,
                                           const IntegratorInputs& inputs);

// Whether `s`'s integrator reads the setting of `row`.
bool IntegratorReads(const JobRenderSettings& s, const RenderSetting& row);

}  // namespace pf
