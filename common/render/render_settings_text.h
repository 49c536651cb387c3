#pragma once
// The render settings as text, made from the table (render_settings_table.h): the photon map's
// key and the EXR header. Both hold every row they should by construction, which
// tests/common/render_settings_table_test.cpp checks against the table.

#include <string>

#include "common/image/image.h"
#include "common/render/job_render_settings.h"

namespace pf {

// "name=value;" for every row that changes a photon map and applies under `s` (a setting
// without effect, e.g. caustic-split-method at caustic-split = 1, leaves the key alone: such maps
// are the same). Requires resolved settings (std::logic_error for direct = auto). Real values in
// the shortest text that reads back to the same double: two values one float step apart give
// two keys.
std::string MapFingerprintOf(const JobRenderSettings& s);

// The EXR header's key for a setting: "settings.<name>".
std::string SettingHeaderKey(std::string_view name);
// Records every row's value as "settings.<name>" (the path tracer's: the rows it reads only).
void RecordRenderSettings(const JobRenderSettings& s, ImageMetadata& meta);

}  // namespace pf
