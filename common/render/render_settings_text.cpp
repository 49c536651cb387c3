#include "common/render/render_settings_text.h"

#include <stdexcept>

#include "common/render/integrator_factory.h"
#include "common/render/render_settings_table.h"

namespace pf {

std::string MapFingerprintOf(const JobRenderSettings& s) {
  if (!s.direct)
    throw std::logic_error("MapFingerprint: direct light is still 'auto' (call JobRenderSettings::Resolved)");
  std::string out;
  for (const RenderSetting& row : RenderSettingsTable())
    if (row.changes_map && (!row.applies || row.applies(s)))
      out += std::string(row.name) + "=" + FormatRenderSettingValue(row.get(s)) + ";";
  return out;
}

std::string JobRenderSettings::MapFingerprint() const {
  return MapFingerprintOf(*this);
}

std::string SettingHeaderKey(std::string_view name) {
  return "settings." + std::string(name);
}

void RecordRenderSettings(const JobRenderSettings& s, ImageMetadata& meta) {
  for (const RenderSetting& row : RenderSettingsTable())
    if (IntegratorReads(s, row)) meta[SettingHeaderKey(row.name)] = FormatRenderSettingValue(row.get(s));
}

}  // namespace pf
