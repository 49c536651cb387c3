#pragma once
// The rules between render settings, in one place (docs/settings.md, "Rules"). The table
// (render_settings_table.h) checks each value alone; these check values against each other, for
// the command line, a settings file, a manifest and a submitted job alike. Each caller names
// the settings in its own words — "spec.settings.photon_map.k" on the wire, "k" in pf — through
// a SettingNamer.
//
// A rule that lives elsewhere: server/scheduling/distributed_maps.cpp decides whether a job's maps
// are traced in pieces (photon-map integrator, map-tracing not local, importance off, a structure
// that serialises); the two map-tracing rules here refuse what it could not honour.

#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "common/render/job_render_settings.h"

namespace pf {

// The caller's spelling of a setting (its table name → "spec.settings.photon_map.caustic_split").
using SettingNamer = std::function<std::string(std::string_view table_name)>;

// Throws InputError (LimitError for the photons × caustic-split budget) naming the first setting
// that contradicts another. The path tracer reads no photon-map setting: none is checked for it.
void CheckRenderSettingRules(const JobRenderSettings& s, const SettingNamer& name);

// A plan that renders the radiance's parts apart (hierarchical, part indirect; radiance_part.h)
// needs the photon-map integrator without the local pass (its parts were measured not to add up
// to the whole radiance with it: up to 7 % apart at some pixels of CornellBox-Sphere). InputError
// naming `part_field`.
void CheckRadiancePartsApart(const JobRenderSettings& s, const std::string& part_field);

// A setting given but without effect under the others: the setting and why
// ("applies to the photon-map integrator only", "applies when local-pass-rays > 0").
struct UnusedSetting {
  std::string name, reason;
};
// Of the settings named in `given` (table names), those that have no effect in `s`. pf makes them
// an error (a person asked for something the image would not show); the coordinator logs them
// for a job (a stored or scripted job keeps working: docs/settings.md, "Settings that do not
// apply").
std::vector<UnusedSetting> UnusedSettings(const JobRenderSettings& s, const std::vector<std::string>& given);
// The names of the settings whose value in `s` differs from the default.
std::vector<std::string> NonDefaultSettings(const JobRenderSettings& s);

}  // namespace pf
