#pragma once
// The table of render settings: every setting of JobRenderSettings declared once, as a row
// (render_setting.h). pf's --set/--settings and its hidden long options, the proto conversion
// (proto/settings_convert.cpp), the map key and the EXR header (render_settings_text.h), `pf
// settings` and docs/settings.md are all made from it, and a test checks that each covers
// exactly the table (tests/common/render_settings_table_test.cpp). Cross-field rules live next to
// it in render_settings_rules.h.
//
// A default is the value of a default-constructed JobRenderSettings (the struct keeps its typed
// fields, which the renderer reads): the table reads it from there rather than repeating it.

#include <string>
#include <string_view>
#include <vector>

#include "common/render/job_render_settings.h"
#include "common/render/render_setting.h"

namespace pf {

// Every row, in the order of docs/settings.md (by group).
const std::vector<RenderSetting>& RenderSettingsTable();

// The row named `name` (kebab-case), or nullptr.
const RenderSetting* FindRenderSetting(std::string_view name);

// Every row's name, in table order (for "did you mean" and listings).
std::vector<std::string> RenderSettingNames();

// The row's value in a default JobRenderSettings.
RenderSettingValue DefaultRenderSettingValue(const RenderSetting& row);

// Parses `text` for the row called `name` and stores it in `s`. InputError naming `label` when
// the name is unknown or the value malformed or out of range (LimitError above a resource limit).
void SetRenderSetting(JobRenderSettings& s, std::string_view name, std::string_view text,
                      const std::string& label);

}  // namespace pf
