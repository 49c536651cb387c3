// The one validation of a job stores it resolved (server/jobs/job_spec.h; docs/farm.md,
// "Validation of a job"): the `auto` settings the scene decides are concrete in the stored spec,
// each choice is reported once, and validating the stored spec again (recovery) changes nothing.

#include "server/jobs/job_spec.h"

#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "common/render/render_settings_table.h"
#include "proto/convert.h"
#include "tests/server/server_test_util.h"
#include "tests/util/input_error.h"

namespace pf::server {
namespace {
namespace v1 = photonfarm::v1;
using testing::kHash;

// One scene, kHash, with the traits an upload records (scene_store.cpp).
class TraitsCatalog final : public SceneCatalog {
 public:
  TraitsCatalog(int caustic_paths, uint32_t lights) : caustic_paths_(caustic_paths), lights_(lights) {}
  std::optional<SceneInfo> FindScene(const std::string& hash) const override {
    if (hash != kHash) return std::nullopt;
    SceneInfo info;
    info.hash = kHash;
    info.entry = "scene.mgf";
    info.caustic_paths = caustic_paths_;
    info.lights = lights_;
    return info;
  }

 private:
  int caustic_paths_;
  uint32_t lights_;
};

v1::JobSpec PhotonMapSpec() {
  v1::JobSpec spec = testing::SkippingSpec(2, 1);
  JobRenderSettings settings;  // every `auto` as a user leaves it
  settings.integrator = IntegratorKind::kPhotonMap;
  settings.photons = 1000;
  SettingsToProto(settings, spec.mutable_settings());
  return spec;
}

// A scene an older coordinator stored without any light (it warned and took it): every worker
// would refuse to load it, so the job is refused at the edge, naming the field.
TEST(JobSpecValidation, ASceneWithoutLightIsRefused) {
  const TraitsCatalog dark(/*caustic_paths=*/0, /*lights=*/0);
  const std::string message = pf::testing::InputErrorOf([&] { ValidateJobSpec(PhotonMapSpec(), dark); });
  EXPECT_EQ(message.rfind("spec.scene_hash: ", 0), 0u) << message;
  EXPECT_NE(message.find("has no light"), std::string::npos) << message;
}

TEST(JobSpecResolution, TheScenesAutoSettingsAreStoredConcrete) {
  const TraitsCatalog glass_one_light(/*caustic_paths=*/1, /*lights=*/1);
  const JobConfig config = ValidateJobSpec(PhotonMapSpec(), glass_one_light);

  EXPECT_EQ(config.settings.caustic, CausticMapMode::kOn);
  ASSERT_TRUE(config.settings.direct.has_value());
  EXPECT_EQ(*config.settings.direct, DirectLightMode::kMonteCarlo);
  ASSERT_EQ(config.auto_choices.size(), 2u);
  EXPECT_EQ(config.auto_choices[0].setting, std::string("caustic-map"));
  EXPECT_EQ(config.auto_choices[1].setting, std::string("direct"));

  // What is stored and echoed holds the concrete values, not `auto`.
  const JobRenderSettings stored = SettingsFromProto(config.spec.settings(), "spec.settings");
  EXPECT_EQ(stored.caustic, CausticMapMode::kOn);
  ASSERT_TRUE(stored.direct.has_value());
  EXPECT_EQ(*stored.direct, DirectLightMode::kMonteCarlo);

  // Recovery validates the stored spec again: same spec, nothing left to choose.
  const JobConfig again = ValidateJobSpec(config.spec, glass_one_light);
  EXPECT_TRUE(again.auto_choices.empty());
  EXPECT_EQ(again.spec.SerializeAsString(), config.spec.SerializeAsString());
}

// pf's own choice (the integrator) arrives in spec.auto_settings; the coordinator's follow it, and
// the stored spec keeps them all (the image header's auto.* keys), once.
TEST(JobSpecResolution, TheChoicesAndTheirReasonsAreStoredWithTheJob) {
  const TraitsCatalog glass_one_light(/*caustic_paths=*/1, /*lights=*/1);
  v1::JobSpec spec = PhotonMapSpec();
  AutoChoiceToProto({"integrator", "photonmap", "mirror or glass surfaces"}, spec.add_auto_settings());
  const JobConfig config = ValidateJobSpec(spec, glass_one_light);
  const std::vector<AutoChoice> stored =
      AutoChoicesFromProto(config.spec.auto_settings(), "spec.auto_settings");
  ASSERT_EQ(stored.size(), 3u);
  EXPECT_EQ(stored[0].setting, "integrator");
  EXPECT_EQ(stored[0].reason, "mirror or glass surfaces");
  EXPECT_EQ(stored[1].setting, "caustic-map");
  EXPECT_EQ(stored[2].setting, "direct");
  EXPECT_EQ(stored[2].reason, config.auto_choices[1].reason);
  const JobConfig again = ValidateJobSpec(config.spec, glass_one_light);
  EXPECT_EQ(again.spec.auto_settings_size(), 3) << "recovery adds nothing";
}

TEST(JobSpecValidation, AutoSettingsAreBoundedTextNamingTheirField) {
  const TraitsCatalog glass_one_light(/*caustic_paths=*/1, /*lights=*/1);
  v1::JobSpec spec = PhotonMapSpec();
  AutoChoiceToProto({"integrator", "path", "line\nforged"}, spec.add_auto_settings());
  std::string message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, glass_one_light); });
  EXPECT_EQ(message.rfind("spec.auto_settings[0].reason ", 0), 0u) << message;
  spec = PhotonMapSpec();
  AutoChoiceToProto({"no-such-setting", "1", "why"}, spec.add_auto_settings());
  message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, glass_one_light); });
  EXPECT_EQ(message.rfind("spec.auto_settings[0].setting: ", 0), 0u) << message;
  spec = PhotonMapSpec();
  AutoChoiceToProto({"integrator", "path", "why"}, spec.add_auto_settings());
  AutoChoiceToProto({"integrator", "photonmap", "why not"}, spec.add_auto_settings());
  message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, glass_one_light); });
  EXPECT_EQ(message.rfind("spec.auto_settings[1].setting: ", 0), 0u) << message;
  EXPECT_NE(message.find("twice"), std::string::npos) << message;
  spec = PhotonMapSpec();
  ASSERT_GE(RenderSettingsTable().size(), limits::kMaxAutoSettings);
  for (size_t i = 0; i + 1 < limits::kMaxAutoSettings; ++i)  // distinct rows, one short of the cap
    AutoChoiceToProto({std::string(RenderSettingsTable()[i].name), "x", "why"}, spec.add_auto_settings());
  message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, glass_one_light); });
  EXPECT_EQ(message.rfind("spec.auto_settings: more than", 0), 0u) << message << ": with the coordinator's 2";
}

TEST(JobSpecValidation, DependenciesAreAFewDistinctIdsNamingTheirField) {
  const TraitsCatalog catalog(/*caustic_paths=*/0, /*lights=*/1);
  v1::JobSpec spec = PhotonMapSpec();
  spec.add_after("job-1");
  spec.add_after("job-2");
  EXPECT_EQ(ValidateJobSpec(spec, catalog).after, (std::vector<std::string>{"job-1", "job-2"}));
  spec.add_after("job-1");
  std::string message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, catalog); });
  EXPECT_EQ(message, "spec.after[2]: 'job-1' is named twice");
  spec = PhotonMapSpec();
  spec.add_after("");
  message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, catalog); });
  EXPECT_EQ(message.rfind("spec.after[0]: empty", 0), 0u) << message;
  spec = PhotonMapSpec();
  for (size_t i = 0; i <= limits::kMaxDependencies; ++i) spec.add_after("job-" + std::to_string(i));
  message = pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, catalog); });
  EXPECT_EQ(message, "spec.after: more than 16 jobs");
}

TEST(JobSpecResolution, ManyLightsAndNoSpecularSurfaceChooseOtherwise) {
  const TraitsCatalog diffuse_many_lights(/*caustic_paths=*/0, /*lights=*/kPhotonDirectMinLights);
  const JobConfig config = ValidateJobSpec(PhotonMapSpec(), diffuse_many_lights);
  EXPECT_EQ(config.settings.caustic, CausticMapMode::kOff);
  ASSERT_TRUE(config.settings.direct.has_value());
  EXPECT_EQ(*config.settings.direct, DirectLightMode::kPhotonDirect);
}

TEST(JobSpecResolution, ASettingTheUserChoseIsKept) {
  v1::JobSpec spec = PhotonMapSpec();
  JobRenderSettings chosen = SettingsFromProto(spec.settings(), "spec.settings");
  chosen.direct = DirectLightMode::kNone;
  SettingsToProto(chosen, spec.mutable_settings());
  const JobConfig config = ValidateJobSpec(spec, TraitsCatalog(1, 1));
  ASSERT_TRUE(config.settings.direct.has_value());
  EXPECT_EQ(*config.settings.direct, DirectLightMode::kNone);
  ASSERT_EQ(config.auto_choices.size(), 1u);  // the caustic map only
  EXPECT_EQ(config.auto_choices[0].setting, std::string("caustic-map"));
}

TEST(JobSpecResolution, UnknownTraitsAndThePathTracerLeaveTheSpecAsSent) {
  // A scene recorded before its traits were (caustic_paths -1): each worker resolves alike.
  const JobConfig old_scene = ValidateJobSpec(PhotonMapSpec(), TraitsCatalog(-1, 1));
  EXPECT_EQ(old_scene.settings.caustic, CausticMapMode::kAuto);
  EXPECT_FALSE(old_scene.settings.direct.has_value());
  EXPECT_TRUE(old_scene.auto_choices.empty());

  const v1::JobSpec path = testing::SkippingSpec(2, 1);
  const JobConfig path_job = ValidateJobSpec(path, TraitsCatalog(1, 1));
  EXPECT_TRUE(path_job.auto_choices.empty());
  EXPECT_EQ(path_job.spec.settings().SerializeAsString(), path.settings().SerializeAsString());
}

}  // namespace
}  // namespace pf::server

namespace pf::server {
namespace {

// An animation of the 12 x 10 test job: `frames` cameras moving along x, the multiple-maps plan.
v1::JobSpec AnimationSpec(int frames) {
  v1::JobSpec spec = testing::SkippingSpec(2, 1);
  spec.mutable_plan()->Clear();
  v1::MultipleMaps* mm = spec.mutable_plan()->mutable_multiple_maps();
  mm->set_maps(2);
  mm->set_samples_per_pixel(1);
  mm->set_tile_size(16);
  spec.mutable_animation()->set_first_frame(7);
  for (int f = 0; f < frames; ++f) {
    v1::Camera* c = spec.mutable_animation()->add_cameras();
    *c = spec.camera();
    c->mutable_eye()->set_x(0.25 * f);
    c->set_width(0);
    c->set_height(0);
  }
  return spec;
}

TEST(JobSpecAnimation, FramesAreTheJobsCamerasAtItsResolutionOverTheStillPlansTasks) {
  const testing::FakeCatalog scenes;
  v1::JobSpec spec = AnimationSpec(3);
  spec.mutable_camera()->mutable_eye()->set_x(0);  // = cameras[0]'s view
  const JobConfig config = ValidateJobSpec(spec, scenes);
  ASSERT_EQ(config.frames.size(), 3u);
  EXPECT_EQ(config.first_frame, 7u);
  EXPECT_EQ(config.image_height(), 30);
  EXPECT_EQ(config.frames[2].eye.x, 0.5);
  EXPECT_EQ(config.frames[2].width, 12);
  EXPECT_EQ(config.frames[2].height, 10);
  EXPECT_EQ(config.camera.eye, config.frames[0].eye);
  const uint64_t still = CountTasks(config.plan, 12, 10);
  EXPECT_EQ(ScheduledTasks(config).size(), 3 * still);
  EXPECT_EQ(ScheduledTaskCount(config), 3 * still);
  TaskSpec last = ScheduledTasks(config).back();
  EXPECT_EQ(last.frame, 2u);
  EXPECT_EQ(config.CameraOf(last).eye.x, 0.5);
  // Stored with every frame's resolution; validating it again (recovery) changes nothing.
  EXPECT_EQ(config.spec.animation().cameras(1).width(), 12u);
  const JobConfig again = ValidateJobSpec(config.spec, scenes);
  EXPECT_EQ(again.spec.SerializeAsString(), config.spec.SerializeAsString());
  EXPECT_EQ(again.frames.size(), 3u);
}

TEST(JobSpecAnimation, WhatCannotBeAnAnimationIsRefusedNamingTheField) {
  const testing::FakeCatalog scenes;
  const auto error = [&](const v1::JobSpec& spec) {
    return pf::testing::InputErrorOf([&] { ValidateJobSpec(spec, scenes); });
  };
  v1::JobSpec empty = AnimationSpec(0);
  empty.mutable_animation()->set_first_frame(1);
  EXPECT_EQ(error(empty).rfind("spec.animation.cameras: empty", 0), 0u) << error(empty);

  v1::JobSpec blind = AnimationSpec(3);
  *blind.mutable_animation()->mutable_cameras(1)->mutable_look_at() = blind.animation().cameras(1).eye();
  EXPECT_EQ(error(blind).rfind("spec.animation.cameras[1].look_at", 0), 0u) << error(blind);

  v1::JobSpec other_size = AnimationSpec(3);
  other_size.mutable_animation()->mutable_cameras(2)->set_width(24);
  other_size.mutable_animation()->mutable_cameras(2)->set_height(20);
  EXPECT_EQ(error(other_size).rfind("spec.animation.cameras[2].width/height: 24x20 differs", 0), 0u)
      << error(other_size);

  v1::JobSpec other_view = AnimationSpec(3);
  other_view.mutable_camera()->mutable_eye()->set_x(9);
  EXPECT_EQ(error(other_view).rfind("spec.camera: its view differs", 0), 0u) << error(other_view);

  v1::JobSpec skipping = AnimationSpec(3);
  skipping.mutable_plan()->mutable_skipping()->set_stride(2);
  skipping.mutable_plan()->mutable_skipping()->set_rounds(1);
  skipping.mutable_plan()->mutable_skipping()->set_samples_per_pixel(1);
  EXPECT_EQ(error(skipping).rfind("spec.plan.skipping: not with spec.animation", 0), 0u) << error(skipping);

  v1::JobSpec automatic = AnimationSpec(3);
  automatic.mutable_plan()->mutable_auto_plan()->set_samples_per_pixel(1);
  EXPECT_EQ(error(automatic).rfind("spec.plan.auto_plan: not with spec.animation", 0), 0u)
      << error(automatic);

  v1::JobSpec too_many = AnimationSpec(int(limits::kMaxFrames) + 1);
  EXPECT_THROW(ValidateJobSpec(too_many, scenes), LimitError);
}

}  // namespace
}  // namespace pf::server
