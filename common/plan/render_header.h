#pragma once
// What an image is of, as its EXR header records it (docs/farm.md, "Image headers"): one
// function writes these keys for pf render, for the coordinator's images (pf get, pf watch -o,
// pf submit --wait -o) and for pf render --workers, so a local render and a farm job of the same
// scene, camera, resolved settings, plan and seed carry the same keys with the same values, and
// pf merge can compare them (SameRenderKey).
//
//   scene                the scene's entry file name (SceneBundle::entry: "cornell.mgf")
//   scene.hash           its bundle's hash (BundleHash: the files, content-addressed)
//   camera.eye, camera.look_at, camera.up   "x,y,z"
//   camera.vfov_degrees
//   settings.<name>      every row of the settings table the integrator reads, resolved
//                        (render_settings_text.h RecordRenderSettings)
//   plan                 PlanRecordText: "multiple-maps maps=4 spp=2 tile=64"
//   seed                 the job's seed
//   auto.<setting>       "value: reason" for each `auto` setting that was resolved (the integrator,
//                        the caustic map, direct light, ...): what was chosen and why
//
// Real numbers read back to the same value (common/core/real_text.h): 3.9f is "3.9".

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/image/image.h"
#include "common/plan/task_plan.h"
#include "common/render/job_render_settings.h"
#include "common/scene/scene.h"

namespace pf {

// The prefix of the auto.<setting> keys (pf merge carries them over when every input agrees).
inline constexpr std::string_view kAutoHeaderPrefix = "auto.";

struct RenderRecord {
  std::string scene;           // SceneBundle::entry
  std::string scene_hash;      // BundleHash
  CameraSpec camera;           // its width × height is the image's size, not recorded
  JobRenderSettings settings;  // resolved (JobRenderSettings::Resolved)
  PlanSpec plan;
  uint64_t seed = 0;
  std::vector<AutoChoice> auto_choices;  // in the order they were made
};

// Writes the keys above into `meta` (replacing any of the same name).
void RecordRender(const RenderRecord& record, ImageMetadata& meta);
// The camera.* keys alone (an animation's frame files replace them with their frame's camera).
void RecordCamera(const CameraSpec& camera, ImageMetadata& meta);

// Whether two images whose headers hold different values under `key` are renders of different
// things — their average mixes them: the scene, the camera and every setting. The plan and the
// seed are not: merging images of other seeds and sample counts is what pf merge is for.
bool SameRenderKey(std::string_view key);

}  // namespace pf
