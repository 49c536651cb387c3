#include "client/settings_args.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "client/did_you_mean.h"
#include "common/core/error.h"
#include "common/render/integrator_factory.h"
#include "common/render/render_settings_rules.h"
#include "common/render/render_settings_table.h"

namespace pf {
namespace {

// "NAME=VALUE" → {NAME, VALUE}.
GivenSetting SplitAssignment(const std::string& text) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0)
    throw InputError("--set: expected NAME=VALUE (pf settings lists the names), got '" + text + "'");
  return {text.substr(0, eq), text.substr(eq + 1), "--set " + text.substr(0, eq)};
}

// A JSON value as a setting's text: numbers as written, strings as they are, booleans as true/false.
std::string JsonText(const nlohmann::json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_integer()) return v.dump();
  if (v.is_number()) return fmt::format("{}", v.get<double>());
  return v.dump();
}

std::vector<GivenSetting> ReadSettingsFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError("--settings " + path + ": cannot be read");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError("--settings " + path + ": not JSON (" + e.what() + ")");
  }
  // A manifest's whole text works too: its "settings" object is the one read.
  if (j.is_object() && j.contains("settings") && j["settings"].is_object()) j = j["settings"];
  if (!j.is_object()) throw InputError("--settings " + path + ": expected a JSON object of NAME: VALUE");
  std::vector<GivenSetting> out;
  for (const auto& [name, value] : j.items())
    out.push_back({name, JsonText(value), path + ": settings." + name});
  return out;
}

void CheckName(const GivenSetting& g) {
  if (FindRenderSetting(g.name)) return;
  std::string hint;
  if (auto match = ClosestName(g.name, RenderSettingNames())) hint = " (did you mean '" + *match + "'?)";
  throw InputError(g.source + ": no setting is called '" + g.name + "'" + hint + "; pf settings lists them");
}

}  // namespace

void AddSettingOptions(CLI::App* app, SettingArgs& a) {
  app->add_option("--set", a.set, "A render setting NAME=VALUE (repeatable; pf settings lists them)")
      ->allow_extra_args(false);
  app->add_option("--settings", a.file, "A JSON file of settings {\"NAME\": VALUE, ...} (as a manifest's)")
      ->check(CLI::ExistingFile);
  // Every setting as a long option, hidden: scripts and docs from before the table keep working.
  for (const RenderSetting& row : RenderSettingsTable()) {
    if (row.name == "integrator") continue;  // a visible option of its own
    const std::string flag = "--" + std::string(row.legacy_flag.empty() ? row.name : row.legacy_flag);
    const std::string name(row.name);
    CLI::Option* opt = nullptr;
    if (row.type == SettingType::kBool) {
      opt = app->add_flag_callback(flag, [&a, name, flag] { a.long_flags.push_back({name, "true", flag}); });
    } else {
      opt = app->add_option_function<std::string>(flag, [&a, name, flag](const std::string& v) {
        a.long_flags.push_back({name, v, flag});
      });
    }
    opt->group("");
  }
  app->add_flag("--irradiance-cache", a.irradiance_cache_flag)->group("");
}

std::vector<GivenSetting> SettingsGiven(const SettingArgs& a) {
  std::vector<GivenSetting> given;  // in the order they apply
  if (!a.file.empty()) given = ReadSettingsFile(a.file);
  given.insert(given.end(), a.long_flags.begin(), a.long_flags.end());
  for (const std::string& text : a.set) given.push_back(SplitAssignment(text));
  const bool error_given = std::any_of(
      given.begin(), given.end(), [](const GivenSetting& g) { return g.name == "irradiance-cache-error"; });
  if (a.irradiance_cache_flag && !error_given)
    given.insert(given.begin(), {"irradiance-cache-error", "0.2", "--irradiance-cache"});
  return given;
}

JobRenderSettings SettingsFromArgs(const SettingArgs& a, const std::string& integrator) {
  JobRenderSettings s;
  SetRenderSetting(s, "integrator", integrator, "--integrator");
  const std::vector<GivenSetting> given = SettingsGiven(a);
  for (const GivenSetting& g : given) CheckName(g);

  // The manifest suggests: what does not apply to this render is skipped, and said.
  std::vector<std::string> skipped;
  for (const GivenSetting& g : a.manifest) {
    const RenderSetting* row = FindRenderSetting(g.name);
    if (std::any_of(given.begin(), given.end(), [&](const GivenSetting& c) { return c.name == g.name; }))
      continue;  // the command line's wins
    if (!IntegratorReads(s, *row)) {
      skipped.push_back(g.name);
      continue;
    }
    row->set(s, ParseRenderSettingValue(*row, g.text, g.source));
    spdlog::info("{} = {} from the manifest's settings (--set {}=... overrides)", g.name, g.text, g.name);
  }
  if (!skipped.empty())
    spdlog::info("the manifest's settings {} are for the photon-map integrator (not used by the path tracer)",
                 fmt::join(skipped, ", "));

  std::vector<std::string> names;
  for (const GivenSetting& g : given) {
    const RenderSetting& row = *FindRenderSetting(g.name);
    row.set(s, ParseRenderSettingValue(row, g.text, g.source));
    names.push_back(g.name);
  }
  for (const UnusedSetting& u : UnusedSettings(s, names)) {
    std::string source;
    for (const GivenSetting& g : given)
      if (g.name == u.name) source = g.source;
    throw InputError(source + ": " + u.reason);
  }
  return s;
}

}  // namespace pf
