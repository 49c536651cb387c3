#include "common/plan/render_header.h"

#include "common/core/real_text.h"
#include "common/render/render_settings_text.h"

namespace pf {

void RecordCamera(const CameraSpec& camera, ImageMetadata& meta) {
  meta["camera.eye"] = RealText(camera.eye);
  meta["camera.look_at"] = RealText(camera.look_at);
  meta["camera.up"] = RealText(Vec3d(camera.up));
  meta["camera.vfov_degrees"] = RealText(camera.vfov_degrees);
}

void RecordRender(const RenderRecord& r, ImageMetadata& meta) {
  meta["scene"] = r.scene;
  meta["scene.hash"] = r.scene_hash;
  RecordCamera(r.camera, meta);
  RecordRenderSettings(r.settings, meta);
  meta["plan"] = PlanRecordText(r.plan);
  meta["seed"] = std::to_string(r.seed);
  for (const AutoChoice& c : r.auto_choices)
    meta[std::string(kAutoHeaderPrefix) + c.setting] = c.value + ": " + c.reason;
}

bool SameRenderKey(std::string_view key) {
  return key == "scene" || key == "scene.hash" || key.starts_with("camera.") ||
         key.starts_with(SettingHeaderKey(""));
}

}  // namespace pf
