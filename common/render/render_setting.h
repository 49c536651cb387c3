#pragma once
// One render setting: a row of the settings table (render_settings_table.h). A row says what the
// setting is called, its type, range, unit and help, what it belongs to, whether it changes a
// photon map, and how to read and write it in a JobRenderSettings. Everything that spells the
// settings — pf's command line, the proto conversion, the map key, the EXR header, `pf settings`
// and docs/settings.md — iterates the rows (docs/settings.md, "One table"), the way pbrt-v4 builds
// an integrator from a ParameterDictionary.

#include <functional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace pf {

struct JobRenderSettings;

enum class SettingType { kBool, kInt, kReal, kChoice };

// What a setting belongs to: a section of docs/settings.md and what reads it. Which integrator
// reads which groups is its registry entry's (integrator_factory.h: the path tracer reads only
// the kRenderer rows, the photon-map integrator all).
enum class SettingGroup {
  kRenderer,      // both integrators
  kPhotonMap,     // the maps: photons, structure, caustic map (Wald 1999, §2.2-2.4)
  kEstimate,      // the radiance estimate (§2.5, §4.1, §4.8)
  kDirectLight,   // direct light (§4.2)
  kLocalPass,     // final gathering (§4.3)
  kImportance,    // importance-driven maps (§4.7)
  kCausticSplit,  // caustic splitting (§4.6)
  kFarm,          // who traces the maps on a farm (docs/farm.md, "Photon maps traced once")
};
const char* SettingGroupTitle(SettingGroup g);

// A setting's value: bool, whole number, real number or the name of a choice.
using RenderSettingValue = std::variant<bool, int64_t, double, std::string>;

struct SettingChoice {
  std::string_view name = {};  // as on the command line: "photon-direct"
  std::string_view help = {};
  // The proto enum value after its type's prefix when it is not `name` in upper snake case
  // ("MONTE_CARLO" for "mc"); proto/settings_convert.cpp.
  std::string_view wire = {};
};

struct RenderSetting {
  std::string_view name =
      {};  // kebab-case; the proto field is its snake_case (caustic-radius ↔ caustic_radius)
  SettingType type = SettingType::kInt;
  SettingGroup group = SettingGroup::kPhotonMap;
  std::string_view help = {};
  std::string_view unit = {};  // "" = a count or a choice
  // kInt and kReal: the range; min_exclusive for (min, max]; max_is_limit: a value above max
  // exceeds a resource limit (LimitError, RESOURCE_EXHAUSTED) rather than being invalid.
  double min = 0, max = 0;
  bool min_exclusive = false, max_is_limit = false;
  std::vector<SettingChoice> choices = {};  // kChoice
  // Whether its value changes a photon map (the map key, MapFingerprintOf, holds exactly these).
  bool changes_map = false;
  // When it has an effect within its group (nullptr = always), and that condition as text:
  // a value given for a setting that has none is an error or a warning, never silently ignored
  // (UnusedSettings, render_settings_rules.h).
  std::function<bool(const JobRenderSettings&)> applies = nullptr;
  std::string_view applies_when = {};
  // The long option pf render had for it before the table, when not --<name> (kept, hidden).
  std::string_view legacy_flag = {};
  // Typed access. `set` takes a value CheckRenderSettingValue accepted.
  std::function<RenderSettingValue(const JobRenderSettings&)> get = nullptr;
  std::function<void(JobRenderSettings&, const RenderSettingValue&)> set = nullptr;

  // Whether it is a field of the wire's photon-map settings (farm.proto PhotonMapSettings) rather
  // than of RenderSettings; a test checks that these are the rows the path tracer does not read.
  bool PhotonMapOnly() const { return group != SettingGroup::kRenderer; }
};

// The value as text, as `ParseRenderSettingValue` reads it and the EXR header records it (a real
// number as the shortest text that reads back to the same double).
std::string FormatRenderSettingValue(const RenderSettingValue& v);
// `text` as a value of `row` ("on"/"off"/"true"/"false"/"1"/"0" for a bool); InputError naming
// `label` (the caller's spelling of the setting: "--set k", "settings.k") if malformed or out of
// range.
RenderSettingValue ParseRenderSettingValue(const RenderSetting& row, std::string_view text,
                                           const std::string& label);
// Checks `v` against the row's type and range: InputError "<label>: must be ..." or, above a
// resource limit, LimitError "<label>: V exceeds the limit M".
void CheckRenderSettingValue(const RenderSetting& row, const RenderSettingValue& v, const std::string& label);
// "1..4096", "[0, 1]", "(0, 1]", ">= 0", or the choices "a|b|c".
std::string DescribeRenderSettingRange(const RenderSetting& row);

}  // namespace pf
