#pragma once
// The render settings of `pf render` and `pf submit`, from the settings table
// (common/render/render_settings_table.h): `--set NAME=VALUE` (repeatable), `--settings FILE` (a
// JSON object of the same schema as a scene manifest's "settings") and the manifest's own
// "settings", plus the long options pf had for each setting before the table (`--photons N`,
// `--map grid`, ...), kept working but hidden from --help (docs/settings.md, "On the command
// line"). Later sources win: manifest < --settings < the long options < --set.

#include <CLI/CLI.hpp>

#include <string>
#include <utility>
#include <vector>

#include "common/render/job_render_settings.h"

namespace pf {

// A setting and its text, with where it came from ("--set", "--photons", "scene.json: settings").
struct GivenSetting {
  std::string name, text, source;
};

struct SettingArgs {
  std::vector<std::string> set;          // --set NAME=VALUE
  std::string file;                      // --settings FILE
  std::vector<GivenSetting> long_flags;  // the hidden long options, as given
  std::vector<GivenSetting> manifest;    // the scene manifest's "settings" rows (ApplyManifestSettings)
  bool irradiance_cache_flag = false;    // the old --irradiance-cache: error 0.2 unless given
};

// --set, --settings and one hidden long option per setting.
void AddSettingOptions(CLI::App* app, SettingArgs& a);

// The settings: `integrator` (pf's --integrator), then the manifest's, the file's, the long
// options' and --set's. InputError naming the source and the setting for an unknown name (with
// "did you mean") or a malformed value. The rules between settings are checked where the job is
// converted, as on the coordinator (PrepareJob → SettingsFromProto: an invalid job, naming its
// field, exit 3). A setting given on the command line or in
// a settings file that does not apply (e.g. photons with the path tracer) is an error: the image
// would not show what was asked for. A manifest's setting that does not apply is only logged,
// since a manifest suggests settings for either integrator.
JobRenderSettings SettingsFromArgs(const SettingArgs& a, const std::string& integrator);

// The settings given in a settings file and on the command line (not the manifest's), in the
// order they apply.
std::vector<GivenSetting> SettingsGiven(const SettingArgs& a);

}  // namespace pf
