#pragma once
// The one place where photonfarm.v1 messages and core (common/) types meet. server/, worker/
// and client/ call these at their edges; common/ never includes generated code.
//
// From-proto functions validate and throw pf::InputError whose message starts with the field
// path ("spec.plan.skipping.stride: must be >= 1"); the RPC layers map that to
// INVALID_ARGUMENT.

#include "common/core/error.h"
#include "common/plan/task_executor.h"
#include "common/plan/task_plan.h"
#include "common/scene/scene.h"
#include "common/scene/scene_bundle.h"
#include "photonfarm/v1/farm.pb.h"
#include "proto/limits.h"

namespace pf {

// The limits of a job's values live with every other limit in proto/limits.h.

// Over a limit: LimitError (common/core/error.h) instead of InputError.

// The lower-case name of a job state ("queued", "running", ...), as pf and the web page show it.
const char* JobStateName(photonfarm::v1::JobState s);

CameraSpec CameraFromProto(const photonfarm::v1::Camera& c, const std::string& field);
void CameraToProto(const CameraSpec& c, photonfarm::v1::Camera* out);

JobRenderSettings SettingsFromProto(const photonfarm::v1::RenderSettings& s, const std::string& field);
void SettingsToProto(const JobRenderSettings& s, photonfarm::v1::RenderSettings* out);
// Writes the progressive schedule's α of a photon-map job into `out` even at its default (call it for
// the progressive plan's jobs and tasks): the default has changed (2/3, then 1/2), and a reader of
// another build, or a stored job read back later, must not take an unset α for its own default
// (docs/farm.md, "Upgrades").
void WriteProgressiveAlpha(const JobRenderSettings& s, photonfarm::v1::RenderSettings* out);

PlanSpec PlanFromProto(const photonfarm::v1::Plan& p, const std::string& field);
void PlanToProto(const PlanSpec& p, photonfarm::v1::Plan* out);
// `spec.plan.auto_plan` (if set) replaced by the plan ChoosePlan (common/plan/plan_choice.h)
// picks for a width × height image: the plan, settings.photon_map.photons = photons per map,
// and plan.chosen_by_auto (the caller logs its reason). `caustic_paths`: the scene has specular
// or glossy surfaces (-1 unknown: assumed). `workers` replaces auto_plan.workers = 0. Returns
// false (no change) for a concrete plan. InputError naming the field under `field` (the spec's
// path: "spec") for invalid input, e.g. "spec.plan.auto_plan.samples_per_pixel: must be >= 1".
bool ResolveAutoPlan(photonfarm::v1::JobSpec* spec, int width, int height, int caustic_paths,
                     uint32_t workers, bool maps_can_be_shipped, const std::string& field);

// spec.auto_settings (what each `auto` became, and why) ↔ core. From-proto checks the count and
// the texts (limits.h) and throws InputError naming `field` ("spec.auto_settings[2].reason: ...").
std::vector<AutoChoice> AutoChoicesFromProto(
    const google::protobuf::RepeatedPtrField<photonfarm::v1::AutoSetting>& in, const std::string& field);
void AutoChoiceToProto(const AutoChoice& c, photonfarm::v1::AutoSetting* out);

PixelSubset PixelSubsetFromProto(const photonfarm::v1::PixelSubset& p, const std::string& field);
void PixelSubsetToProto(const PixelSubset& p, photonfarm::v1::PixelSubset* out);

// Task ↔ core: the task's core TaskSpec (the camera and settings travel alongside).
TaskSpec TaskSpecFromProto(const photonfarm::v1::Task& t);
void TaskSpecToProto(const TaskSpec& spec, photonfarm::v1::Task* out);

// The bundle as UploadScene sends it (the coordinator checks it).
void BundleToProto(const SceneBundle& bundle, photonfarm::v1::SceneBundle* out);

}  // namespace pf
