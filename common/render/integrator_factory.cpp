#include "common/render/integrator_factory.h"

#include <algorithm>
#include <stdexcept>

#include "common/core/error.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"

namespace pf {
namespace {

// Resource limits (LimitError) are a job's, checked where it enters (docs/security.md,
// "Limits"); the integrators render beyond them (hard_cases_test.cpp renders k = 100000), so a
// builder refuses what is invalid, not what is large.
template <typename F>
void IgnoringLimits(F&& check) {
  try {
    check();
  } catch (const LimitError&) {
  }
}

// Every setting `kind` reads, alone (the table's type and range) and, for the photon-map
// integrator, against the others (render_settings_rules.h): settings made in code rather than
// parsed from text are checked too, naming the setting as the table does.
void CheckSettingsRead(IntegratorKind kind, const JobRenderSettings& s) {
  const IntegratorEntry& entry = Integrators().FindKind(kind);
  for (const RenderSetting& row : RenderSettingsTable())
    if (entry.Reads(row))
      IgnoringLimits([&] { CheckRenderSettingValue(row, row.get(s), std::string(row.name)); });
  IgnoringLimits(
      [&] { CheckRenderSettingRules(s, [](std::string_view name) { return std::string(name); }); });
}

void CheckScene(const IntegratorInputs& in, const char* who) {
  if (!in.scene || !in.lights) throw std::logic_error(std::string(who) + ": no scene or lights");
}

std::unique_ptr<Integrator> BuildPathTracer(const JobRenderSettings& s, const IntegratorInputs& in) {
  CheckSettingsRead(IntegratorKind::kPath, s);
  CheckScene(in, "path tracer");
  return std::make_unique<PathTracer>(*in.scene, *in.lights);
}

std::unique_ptr<Integrator> BuildPhotonMapIntegrator(const JobRenderSettings& s, const IntegratorInputs& in) {
  CheckSettingsRead(IntegratorKind::kPhotonMap, s);
  CheckScene(in, "photon-map integrator");
  if (!in.maps) throw std::logic_error("photon-map integrator: no photon maps");
  PhotonMapIntegratorOptions options = s.IntegratorOptions(in.scene->bounds());
  options.precomputed.threads = in.threads;
  options.part = in.part;
  if (in.pass_radius > 0.0f)
    for (RadianceEstimateOptions* o : {&options.global, &options.caustic, &options.direct_photons}) {
      o->radius_query = true;
      o->max_radius = in.pass_radius;
    }
  return std::make_unique<PhotonMapIntegrator>(*in.scene, in.lights, *in.maps, options);
}

}  // namespace

bool IntegratorEntry::Reads(const RenderSetting& row) const {
  return std::find(groups.begin(), groups.end(), row.group) != groups.end();
}

bool IntegratorEntry::UsesPhotonMaps() const {
  return std::find(groups.begin(), groups.end(), SettingGroup::kPhotonMap) != groups.end();
}

const NamedRegistry<IntegratorEntry>& Integrators() {
  using G = SettingGroup;
  static const NamedRegistry<IntegratorEntry> registry(
      "integrator", {{.name = "path",
                      .kind = IntegratorKind::kPath,
                      .title = "the path tracer",
                      .groups = {G::kRenderer},
                      .build = BuildPathTracer},
                     {.name = "photonmap",
                      .kind = IntegratorKind::kPhotonMap,
                      .title = "the photon-map integrator",
                      .groups = {G::kRenderer, G::kPhotonMap, G::kEstimate, G::kDirectLight, G::kLocalPass,
                                 G::kImportance, G::kCausticSplit, G::kFarm},
                      .build = BuildPhotonMapIntegrator}});
  return registry;
}

std::unique_ptr<Integrator> MakeIntegrator(std::string_view name, const JobRenderSettings& settings,
                                           const IntegratorInputs& inputs) {
  const IntegratorEntry& entry = Integrators().Find(name, "integrator");
  if (settings.integrator == entry.kind) return entry.build(settings, inputs);
  JobRenderSettings s = settings;  // the rules between settings read which integrator they are for
  s.integrator = entry.kind;
  return entry.build(s, inputs);
}

bool IntegratorReads(const JobRenderSettings& s, const RenderSetting& row) {
  return Integrators().FindKind(s.integrator).Reads(row);
}

}  // namespace pf
