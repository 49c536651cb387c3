// Validation of client requests through the real RenderServiceImpl on an in-process gRPC server
// (127.0.0.1:0, real channel, no mocks): each bad request gets the exact status code and a
// message naming the field, and nothing is stored. Plus the bearer tokens and roles of both services.
#include <gmock/gmock.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>

#include <cmath>
#include <condition_variable>
#include <functional>
#include <limits>
#include <mutex>

#include "photonfarm_version.h"
#include "proto/convert.h"
#include "server/store/scene_store.h"
#include "tests/server/server_test_util.h"
#include "tests/util/generic_call.h"
#include "tests/util/job_specs.h"

namespace pf::server {
namespace {
using testing::Ctx;
using ::testing::HasSubstr;
using testing::LiveCoordinator;
using testing::TempDir;
namespace v1 = photonfarm::v1;

class RenderServiceTest : public testing::LiveCoordinatorTest {
 protected:
  v1::JobSpec ValidSpec() const {
    return test_util::CornellPhotonMapSpec(hash_, 32, 24, /*rounds=*/2, /*seed=*/3);
  }

  grpc::Status Submit(const v1::JobSpec& spec, v1::SubmitJobResponse* resp = nullptr) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = spec;
    v1::SubmitJobResponse ignored;
    return live_->render->SubmitJob(Ctx().get(), req, resp ? resp : &ignored);
  }
};

struct BadCase {
  const char* name;
  std::function<void(v1::JobSpec&)> mutate;
  grpc::StatusCode code;
  const char* message;  // the message starts with this (the field path)
};

TEST_F(RenderServiceTest, EveryBadJobGetsTheRightCodeAndNamesTheField) {
  using C = grpc::StatusCode;
  const std::vector<BadCase> cases = {
      {"zero photons", [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_photons(0); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.photons: must be >= 1"},
      {"too many photons",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_photons(uint64_t(1) << 40); },
       C::RESOURCE_EXHAUSTED, "spec.settings.photon_map.photons: 1099511627776 exceeds the limit"},
      {"zero k", [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_k(0); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.k: must be >= 1"},
      {"no integrator", [](v1::JobSpec& s) { s.mutable_settings()->clear_integrator(); }, C::INVALID_ARGUMENT,
       "spec.settings.integrator:"},
      {"unknown direct light",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_direct(v1::DirectLight(99)); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.direct: unknown value"},
      {"zero shadow rays",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_shadow_rays(0); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.shadow_rays: must be in 1..4096"},
      {"uniform fraction 2",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_light_uniform_fraction(2); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.light_uniform_fraction: must be in [0, 1]"},
      {"NaN cache",
       [](v1::JobSpec& s) {
         s.mutable_settings()->mutable_photon_map()->set_photon_direct_cache(std::nan(""));
       },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.photon_direct_cache: must be in [0, 1]"},
      {"zero PhotonDirect k",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_photon_direct_k(0); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.photon_direct_k: must be in 1..10000"},
      {"local pass 5000",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_local_pass_rays(5000); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.local_pass_rays: must be <= 4096"},
      {"adaptive k above k",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_adaptive_k_min(21); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.adaptive_k_min: must be <= k (20)"},
      {"unknown kd split",
       [](v1::JobSpec& s) { s.mutable_settings()->mutable_photon_map()->set_kd_split(v1::KdSplit(7)); },
       C::INVALID_ARGUMENT, "spec.settings.photon_map.kd_split: unknown value"},
      {"0x0 image with a camera",
       [](v1::JobSpec& s) {
         s.mutable_camera()->set_width(0);
         s.mutable_camera()->set_height(0);
       },
       C::INVALID_ARGUMENT, "spec.camera.width/height: must be > 0"},
      {"width without height",
       [](v1::JobSpec& s) {
         s.clear_camera();
         s.mutable_camera()->set_width(64);
       },
       C::INVALID_ARGUMENT, "spec.camera.width/height: set both"},
      {"huge image",
       [](v1::JobSpec& s) {
         s.mutable_camera()->set_width(100000);
         s.mutable_camera()->set_height(100000);
       },
       C::RESOURCE_EXHAUSTED, "spec.camera.width/height: 100000x100000 exceeds the limit"},
      {"eye equals look_at", [](v1::JobSpec& s) { s.mutable_camera()->mutable_look_at()->set_z(3.9); },
       C::INVALID_ARGUMENT, "spec.camera.look_at: must differ from eye"},
      {"fov 180", [](v1::JobSpec& s) { s.mutable_camera()->set_vfov_degrees(180); }, C::INVALID_ARGUMENT,
       "spec.camera.vfov_degrees"},
      // Valid as doubles, 0 and 180 as the worker's floats.
      {"fov 1e-300", [](v1::JobSpec& s) { s.mutable_camera()->set_vfov_degrees(1e-300); },
       C::INVALID_ARGUMENT, "spec.camera.vfov_degrees"},
      {"fov 179.9999999", [](v1::JobSpec& s) { s.mutable_camera()->set_vfov_degrees(179.9999999); },
       C::INVALID_ARGUMENT, "spec.camera.vfov_degrees"},
      // Names are logged; control characters would forge log lines or drive terminals.
      {"name with a newline", [](v1::JobSpec& s) { s.set_name("a\n[error] forged"); }, C::INVALID_ARGUMENT,
       "spec.name 'a\\x0a[error] forged': contains a control character"},
      {"name with ANSI", [](v1::JobSpec& s) { s.set_name("\x1b[2Jx"); }, C::INVALID_ARGUMENT,
       "spec.name '\\x1b[2Jx': contains a control character"},
      {"NaN eye", [](v1::JobSpec& s) { s.mutable_camera()->mutable_eye()->set_x(std::nan("")); },
       C::INVALID_ARGUMENT, "spec.camera.eye: must be three finite numbers"},
      {"no plan", [](v1::JobSpec& s) { s.clear_plan(); }, C::INVALID_ARGUMENT, "spec.plan: one of"},
      {"stride 0", [](v1::JobSpec& s) { s.mutable_plan()->mutable_skipping()->set_stride(0); },
       C::INVALID_ARGUMENT, "spec.plan.skipping.stride: must be >= 1"},
      {"stride too large", [](v1::JobSpec& s) { s.mutable_plan()->mutable_skipping()->set_stride(28); },
       C::INVALID_ARGUMENT, "spec.plan.skipping.stride: S² = 784 exceeds the number of pixels"},
      {"rounds 0", [](v1::JobSpec& s) { s.mutable_plan()->mutable_skipping()->set_rounds(0); },
       C::INVALID_ARGUMENT, "spec.plan.skipping.rounds: must be >= 1"},
      {"spp 0", [](v1::JobSpec& s) { s.mutable_plan()->mutable_skipping()->set_samples_per_pixel(0); },
       C::INVALID_ARGUMENT, "spec.plan.skipping.samples_per_pixel: must be >= 1"},
      {"spp over limit",
       [](v1::JobSpec& s) { s.mutable_plan()->mutable_skipping()->set_samples_per_pixel(1u << 20); },
       C::RESOURCE_EXHAUSTED, "spec.plan.skipping.samples_per_pixel: exceeds the limit"},
      {"zero maps",
       [](v1::JobSpec& s) {
         s.mutable_plan()->mutable_multiple_maps()->set_maps(0);
         s.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
       },
       C::INVALID_ARGUMENT, "spec.plan.multiple_maps.maps: must be >= 1"},
      {"too many tasks",
       [](v1::JobSpec& s) {
         s.mutable_plan()->mutable_multiple_maps()->set_maps(100000);
         s.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
         s.mutable_plan()->mutable_multiple_maps()->set_tile_size(4);
       },
       C::RESOURCE_EXHAUSTED, "spec.plan: 4800000 tasks exceed the limit of 1048576"},
      {"one task too large for a message",
       [](v1::JobSpec& s) {
         s.mutable_camera()->set_width(4096);
         s.mutable_camera()->set_height(4096);
         s.mutable_plan()->mutable_multiple_maps()->set_maps(1);
         s.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
       },
       C::RESOURCE_EXHAUSTED, "spec.plan.multiple_maps: a task of 16777216 pixels exceeds the limit"},
      {"hierarchy of the map part with the local pass",
       [](v1::JobSpec& s) {
         v1::Hierarchical* h = s.mutable_plan()->mutable_hierarchical();
         h->set_levels(2);
         h->set_dims(2);
         h->set_base_samples(2);
         h->set_min_samples(1);
         h->set_decay(2);
         h->set_samples_per_pixel(1);
         h->set_part(v1::HIERARCHY_PART_INDIRECT);
         h->set_direct_samples_per_pixel(2);
         s.mutable_settings()->mutable_photon_map()->set_local_pass_rays(4);
       },
       C::INVALID_ARGUMENT, "spec.plan.hierarchical.part: indirect is not available with the local pass"},
      {"tail tiles that cut a pixel block",
       [](v1::JobSpec& s) {
         s.mutable_plan()->mutable_multiple_maps()->set_maps(1);
         s.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
         s.mutable_plan()->mutable_multiple_maps()->set_tile_size(32);
         s.mutable_plan()->mutable_multiple_maps()->set_tail_tile_size(8);
       },
       C::INVALID_ARGUMENT, "spec.plan.multiple_maps.tail_tile_size: 8 must be 0 or a multiple of 16"},
      {"negative time budget", [](v1::JobSpec& s) { s.mutable_stop()->set_time_budget_seconds(-1); },
       C::INVALID_ARGUMENT, "spec.stop.time_budget_seconds: must be a finite number >= 0"},
      {"NaN noise target", [](v1::JobSpec& s) { s.mutable_stop()->set_target_noise_rms(std::nan("")); },
       C::INVALID_ARGUMENT, "spec.stop.target_noise_rms"},
      {"long name", [](v1::JobSpec& s) { s.set_name(std::string(300, 'n')); }, C::INVALID_ARGUMENT,
       "spec.name: longer than 256 bytes"},
      {"no scene", [](v1::JobSpec& s) { s.clear_scene_hash(); }, C::INVALID_ARGUMENT,
       "spec.scene_hash: required"},
      {"malformed scene hash", [](v1::JobSpec& s) { s.set_scene_hash("xyz"); }, C::INVALID_ARGUMENT,
       "spec.scene_hash: must be 64 lowercase hex digits"},
      {"unknown scene hash", [](v1::JobSpec& s) { s.set_scene_hash(std::string(64, '0')); }, C::NOT_FOUND,
       "spec.scene_hash: unknown scene '0000"},
  };
  for (const BadCase& c : cases) {
    v1::JobSpec spec = ValidSpec();
    c.mutate(spec);
    const grpc::Status st = Submit(spec);
    EXPECT_EQ(st.error_code(), c.code) << c.name << ": " << st.error_message();
    EXPECT_EQ(st.error_message().rfind(c.message, 0), 0u)
        << c.name << ": got '" << st.error_message() << "', expected it to start with '" << c.message << "'";
  }
  // Nothing was stored or queued.
  v1::ListJobsRequest list;
  list.set_include_finished(true);
  v1::ListJobsResponse jobs;
  ASSERT_TRUE(live_->render->ListJobs(Ctx().get(), list, &jobs).ok());
  EXPECT_EQ(jobs.jobs_size(), 0);
  // And the valid spec is accepted.
  v1::SubmitJobResponse resp;
  const grpc::Status st = Submit(ValidSpec(), &resp);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_THAT(resp.job_id(), ::testing::MatchesRegex("job-[0-9a-f]{32}"));
}

// One cap for tasks per job (proto/limits.h), exactly at the boundary: 2^20 tasks validate,
// 2^20 + 1 = 17 · 61681 are RESOURCE_EXHAUSTED (the plan code used to allow 2^24, the farm 2^20).
TEST_F(RenderServiceTest, TaskCapIsOneLimitExactlyAtTwoToTheTwenty) {
  struct OneScene : SceneCatalog {
    SceneInfo info;
    std::optional<SceneInfo> FindScene(const std::string& hash) const override {
      return hash == info.hash ? std::optional<SceneInfo>(info) : std::nullopt;
    }
  } catalog;
  catalog.info.hash = hash_;
  catalog.info.entry = "cornell-box.json";
  catalog.info.lights = 1;
  auto maps_spec = [&](uint32_t maps, uint32_t width) {
    v1::JobSpec spec = ValidSpec();
    spec.mutable_camera()->set_width(width);
    spec.mutable_camera()->set_height(1);
    spec.mutable_plan()->mutable_multiple_maps()->set_maps(maps);
    spec.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
    spec.mutable_plan()->mutable_multiple_maps()->set_tile_size(1);
    return spec;
  };
  ASSERT_EQ(limits::kMaxTasksPerJob, uint64_t(1) << 20);
  // Exactly the limit: valid (checked without creating a million tasks).
  const JobConfig at = ValidateJobSpec(maps_spec(65536, 16), catalog);
  EXPECT_EQ(CountTasks(at.plan, at.camera.width, at.camera.height), limits::kMaxTasksPerJob);
  // One more: refused, by the validation and by a live SubmitJob, naming the number and the limit.
  const v1::JobSpec over = maps_spec(61681, 17);
  try {
    ValidateJobSpec(over, catalog);
    ADD_FAILURE() << "2^20 + 1 tasks were accepted";
  } catch (const LimitError& e) {
    EXPECT_THAT(e.what(), HasSubstr("spec.plan: 1048577 tasks exceed the limit of 1048576 per job"));
  }
  const grpc::Status st = Submit(over);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << st.error_message();
  EXPECT_THAT(st.error_message(), HasSubstr("1048577 tasks exceed the limit of 1048576"));
  // The local plan check (pf render) is the same function.
  EXPECT_EQ(limits::TaskCountProblem(limits::kMaxTasksPerJob), "");
  EXPECT_NE(limits::TaskCountProblem(limits::kMaxTasksPerJob + 1), "");
}

// The per-job result bound is 1024 x the scene's brightest emitter (the Cornell box:
// Le = (17, 12, 4)), measured when the scene is uploaded; unknown (-1, an old database) = none.
TEST_F(RenderServiceTest, TheResultBoundComesFromTheScenesBrightestEmitter) {
  struct OneScene : SceneCatalog {
    SceneInfo info;
    std::optional<SceneInfo> FindScene(const std::string&) const override { return info; }
  } catalog;
  catalog.info.hash = hash_;
  catalog.info.entry = "cornell-box.json";
  catalog.info.lights = 1;
  catalog.info.max_emission = -1;
  EXPECT_EQ(ValidateJobSpec(ValidSpec(), catalog).max_sample_radiance,
            std::numeric_limits<double>::infinity());
  // The uploaded Cornell box, through the coordinator's own catalog.
  const JobConfig config = ValidateJobSpec(ValidSpec(), live_->coordinator->scenes());
  EXPECT_EQ(config.max_sample_radiance, 1024.0 * 17.0);
}

// ListJobs pages (a full listing of 10k jobs was 4.4 MB, over gRPC's default 4 MiB).
TEST_F(RenderServiceTest, ListJobsPagesInSubmissionOrderAndRefusesForeignTokens) {
  std::vector<std::string> submitted;
  for (int i = 0; i < 7; ++i) {
    v1::SubmitJobResponse resp;
    ASSERT_TRUE(Submit(ValidSpec(), &resp).ok());
    submitted.push_back(resp.job_id());
  }
  v1::CancelJobRequest cancel;
  cancel.set_job_id(submitted[4]);  // finished: listed only with include_finished
  v1::CancelJobResponse cancelled;
  ASSERT_TRUE(live_->render->CancelJob(Ctx().get(), cancel, &cancelled).ok());

  auto list_all = [&](bool include_finished, uint32_t page_size, std::vector<int>* page_sizes) {
    std::vector<std::string> ids;
    v1::ListJobsRequest req;
    req.set_include_finished(include_finished);
    req.set_page_size(page_size);
    for (int guard = 0; guard < 100; ++guard) {
      v1::ListJobsResponse resp;
      const grpc::Status st = live_->render->ListJobs(Ctx().get(), req, &resp);
      EXPECT_TRUE(st.ok()) << st.error_message();
      page_sizes->push_back(resp.jobs_size());
      for (const v1::JobStatus& j : resp.jobs()) ids.push_back(j.job_id());
      if (resp.next_page_token().empty()) break;
      req.set_page_token(resp.next_page_token());
    }
    return ids;
  };
  std::vector<int> sizes;
  EXPECT_EQ(list_all(true, 3, &sizes), submitted);
  EXPECT_EQ(sizes, (std::vector<int>{3, 3, 1}));
  sizes.clear();
  std::vector<std::string> active = submitted;
  active.erase(active.begin() + 4);
  EXPECT_EQ(list_all(false, 2, &sizes), active);
  EXPECT_EQ(sizes, (std::vector<int>{2, 2, 2})) << "the last page is known to be last";
  sizes.clear();
  EXPECT_EQ(list_all(true, 0, &sizes), submitted) << "0 = the default page size";
  EXPECT_EQ(sizes, (std::vector<int>{7}));
  sizes.clear();
  EXPECT_EQ(list_all(true, 4000000000u, &sizes), submitted) << "over the cap: capped, not refused";
  EXPECT_EQ(limits::kMaxListJobsPageSize, 1000u);

  for (const std::string& bad :
       std::vector<std::string>{"garbage", "p1.", "p1.0", "p1.-3", "p1.12x", "p1.99999999999999999999",
                                std::string(1000, 'p'), std::string("p1.1\n")}) {
    v1::ListJobsRequest req;
    req.set_page_token(bad);
    v1::ListJobsResponse resp;
    const grpc::Status st = live_->render->ListJobs(Ctx().get(), req, &resp);
    EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << bad;
    EXPECT_EQ(st.error_message(), "page_token: not a next_page_token of an earlier ListJobs answer") << bad;
  }
  // A token past the last job is a valid, empty last page.
  v1::ListJobsRequest req;
  req.set_page_token("p1.999");
  v1::ListJobsResponse resp;
  ASSERT_TRUE(live_->render->ListJobs(Ctx().get(), req, &resp).ok());
  EXPECT_EQ(resp.jobs_size(), 0);
  EXPECT_EQ(resp.next_page_token(), "");
}

TEST(SettingsConversion, EveryChapterFourSettingSurvivesTheRoundTrip) {
  JobRenderSettings s;
  s.photons = 1234;
  s.k = 77;
  s.kd_split = KdSplitRule::kLevelCycle;
  s.direct = DirectLightMode::kPhotonDirect;
  s.shadow_rays = 5;
  s.light_uniform_fraction = 0.25f;
  s.photon_direct_k = 40;
  s.non_contributing = NonContributingMode::kEachOne;
  s.photon_direct_cache = 0.0f;  // off: must not read back as the default 0.25
  s.local_pass_rays = 9;
  s.occlusion_test = true;
  s.adaptive_k_min = 11;
  s.sampler = SamplerKind::kIndependent;
  v1::RenderSettings proto;
  SettingsToProto(s, &proto);
  const JobRenderSettings r = SettingsFromProto(proto, "settings");
  EXPECT_EQ(r.photons, s.photons);
  EXPECT_EQ(r.k, s.k);
  EXPECT_EQ(r.kd_split, s.kd_split);
  EXPECT_EQ(r.direct, s.direct);
  EXPECT_EQ(r.shadow_rays, s.shadow_rays);
  EXPECT_EQ(r.light_uniform_fraction, s.light_uniform_fraction);
  EXPECT_EQ(r.photon_direct_k, s.photon_direct_k);
  EXPECT_EQ(r.non_contributing, s.non_contributing);
  EXPECT_EQ(r.photon_direct_cache, 0.0f);
  EXPECT_EQ(r.local_pass_rays, s.local_pass_rays);
  EXPECT_EQ(r.occlusion_test, s.occlusion_test);
  EXPECT_EQ(r.adaptive_k_min, s.adaptive_k_min);
  EXPECT_EQ(r.sampler, SamplerKind::kIndependent);
  EXPECT_EQ(r.MapFingerprint(), s.MapFingerprint());
  // The sampler changes the photons, so it is part of the map's cache key.
  JobRenderSettings sobol = s;
  sobol.sampler = SamplerKind::kSobol;
  EXPECT_NE(sobol.MapFingerprint(), s.MapFingerprint());
  // Unset (older clients) means Sobol, the default; an unknown value is rejected by name.
  v1::RenderSettings unset = proto;
  unset.clear_sampler();
  EXPECT_EQ(SettingsFromProto(unset, "settings").sampler, SamplerKind::kSobol);
  unset.set_sampler(v1::Sampler(7));
  try {
    SettingsFromProto(unset, "settings");
    ADD_FAILURE() << "unknown sampler accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("settings.sampler"), std::string::npos) << e.what();
  }

  // Unset fields mean the documented defaults, and DIRECT_LIGHT_UNSPECIFIED means auto.
  v1::RenderSettings minimal;
  minimal.set_integrator(v1::INTEGRATOR_PHOTONMAP);
  minimal.mutable_photon_map()->set_photons(10);
  minimal.mutable_photon_map()->set_k(10);
  const JobRenderSettings d = SettingsFromProto(minimal, "settings");
  const JobRenderSettings defaults;
  EXPECT_FALSE(d.direct.has_value());
  EXPECT_EQ(d.shadow_rays, defaults.shadow_rays);
  EXPECT_EQ(d.photon_direct_k, defaults.photon_direct_k);
  EXPECT_EQ(d.photon_direct_cache, defaults.photon_direct_cache);
  EXPECT_EQ(d.kd_split, defaults.kd_split);
  v1::RenderSettings again;
  SettingsToProto(d, &again);
  // auto, the default, is written unset (proto/settings_convert.cpp) and reads back as auto.
  EXPECT_EQ(again.photon_map().direct(), v1::DIRECT_LIGHT_UNSPECIFIED);
  EXPECT_FALSE(SettingsFromProto(again, "settings").direct.has_value());
}

TEST_F(RenderServiceTest, UnsetCameraUsesTheManifestCamera) {
  v1::JobSpec spec = ValidSpec();
  spec.clear_camera();
  v1::SubmitJobResponse resp;
  ASSERT_TRUE(Submit(spec, &resp).ok());
  v1::GetJobRequest get;
  get.set_job_id(resp.job_id());
  v1::JobStatus status;
  ASSERT_TRUE(live_->render->GetJob(Ctx().get(), get, &status).ok());
  EXPECT_EQ(status.spec().camera().width(), 512u);  // cornell-box.json
  EXPECT_NEAR(status.spec().camera().vfov_degrees(), 39.3, 1e-5);
  EXPECT_EQ(status.state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(status.tasks_total(), 8u);
  // Only a resolution: the manifest camera at that size.
  spec.mutable_camera()->set_width(40);
  spec.mutable_camera()->set_height(30);
  ASSERT_TRUE(Submit(spec, &resp).ok());
  get.set_job_id(resp.job_id());
  ASSERT_TRUE(live_->render->GetJob(Ctx().get(), get, &status).ok());
  EXPECT_EQ(status.spec().camera().width(), 40u);
  EXPECT_NEAR(status.spec().camera().eye().z(), 3.9, 1e-5);
}

TEST_F(RenderServiceTest, ScenesAreValidatedAndUploadIsIdempotent) {
  v1::UploadSceneRequest again;
  *again.mutable_bundle() = testing::ToProto(CollectBundle(testing::CornellManifest()));
  v1::UploadSceneResponse resp;
  ASSERT_TRUE(live_->render->UploadScene(Ctx().get(), again, &resp).ok());
  EXPECT_EQ(resp.scene_hash(), hash_);
  EXPECT_GT(resp.triangles(), 0u);
  EXPECT_EQ(resp.lights(), 1u);

  v1::UploadSceneRequest broken;
  broken.mutable_bundle()->set_entry("room.mgf");
  v1::SceneFile* f = broken.mutable_bundle()->add_files();
  f->set_path("room.mgf");
  f->set_content("# a room\nv a =\n p 0 0 0\nf a nowhere elsewhere\n");
  grpc::Status st = live_->render->UploadScene(Ctx().get(), broken, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("room.mgf:4:", 0), 0u) << st.error_message();

  v1::UploadSceneRequest escape;
  escape.mutable_bundle()->set_entry("a.mgf");
  escape.mutable_bundle()->add_files()->set_path("a.mgf");
  escape.mutable_bundle()->add_files()->set_path("../../etc/x");
  st = live_->render->UploadScene(Ctx().get(), escape, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(st.error_message(), HasSubstr("bundle.files[1].path '../../etc/x': '..' component"));

  v1::UploadSceneRequest empty;
  st = live_->render->UploadScene(Ctx().get(), empty, &resp);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(st.error_message(), HasSubstr("bundle.files"));
}

TEST_F(RenderServiceTest, UnknownJobsAreNotFound) {
  v1::GetJobRequest get;
  get.set_job_id("job-404");
  v1::JobStatus status;
  grpc::Status st = live_->render->GetJob(Ctx().get(), get, &status);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(st.error_message(), "job_id: unknown job 'job-404'");
  v1::CancelJobRequest cancel;
  cancel.set_job_id("job-404");
  v1::CancelJobResponse cr;
  EXPECT_EQ(live_->render->CancelJob(Ctx().get(), cancel, &cr).error_code(), grpc::StatusCode::NOT_FOUND);
  get.set_job_id("");
  EXPECT_EQ(live_->render->GetJob(Ctx().get(), get, &status).error_code(),
            grpc::StatusCode::INVALID_ARGUMENT);
  v1::GetImageRequest img;
  img.set_job_id("job-404");
  auto ctx = Ctx();
  auto reader = live_->render->GetImage(ctx.get(), img);
  v1::ImageChunk chunk;
  EXPECT_FALSE(reader->Read(&chunk));
  EXPECT_EQ(reader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
  v1::WatchJobRequest watch;
  watch.set_job_id("job-404");
  auto wctx = Ctx();
  auto wreader = live_->render->WatchJob(wctx.get(), watch);
  v1::JobUpdate update;
  EXPECT_FALSE(wreader->Read(&update));
  EXPECT_EQ(wreader->Finish().error_code(), grpc::StatusCode::NOT_FOUND);
}

// A unique prefix of an id (without "job-") works in every RPC that takes one and the answers name
// the whole id; the image and the events are the job's (docs/farm.md "Job ids").
TEST_F(RenderServiceTest, AUniqueIdPrefixWorksInEveryJobRpc) {
  v1::SubmitJobResponse submitted;
  ASSERT_TRUE(Submit(ValidSpec(), &submitted).ok());
  const std::string id = submitted.job_id();
  const std::string prefix = id.substr(4, 8);
  v1::CancelJobRequest cancel;  // finished: its image is served from the checkpoint
  cancel.set_job_id(prefix);
  v1::CancelJobResponse cancelled;
  grpc::Status st = live_->render->CancelJob(Ctx().get(), cancel, &cancelled);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(cancelled.status().job_id(), id);
  v1::GetJobRequest get;
  get.set_job_id(prefix);
  v1::JobStatus status;
  st = live_->render->GetJob(Ctx().get(), get, &status);
  ASSERT_TRUE(st.ok()) << st.error_message();
  EXPECT_EQ(status.job_id(), id);
  EXPECT_EQ(status.state(), v1::JOB_STATE_CANCELLED);
  v1::ListJobEventsRequest events;
  events.set_job_id(prefix);
  v1::ListJobEventsResponse ev;
  st = live_->render->ListJobEvents(Ctx().get(), events, &ev);
  EXPECT_TRUE(st.ok()) << st.error_message();
  v1::WatchJobRequest watch;
  watch.set_job_id(prefix);
  auto wctx = Ctx();
  auto wreader = live_->render->WatchJob(wctx.get(), watch);
  v1::JobUpdate update;
  ASSERT_TRUE(wreader->Read(&update));
  EXPECT_EQ(update.status().job_id(), id);
  while (wreader->Read(&update)) {
  }
  EXPECT_TRUE(wreader->Finish().ok());
  for (const std::string& typed : {prefix, "job-" + prefix}) {
    v1::GetImageRequest img;
    img.set_job_id(typed);
    auto ctx = Ctx();
    auto reader = live_->render->GetImage(ctx.get(), img);
    v1::ImageChunk chunk;
    size_t chunks = 0;
    while (reader->Read(&chunk)) ++chunks;
    st = reader->Finish();
    EXPECT_TRUE(st.ok()) << typed << ": " << st.error_message();
    EXPECT_GT(chunks, 0u);
  }
}

// An 8000-byte job id was echoed into the error (the client saw RESOURCE_EXHAUSTED
// for the oversized status); a 1 MiB lease id wrote a 1 MiB log line per call. Ids are checked
// at the edge: bounded, printable, and never echoed in full.
TEST_F(RenderServiceTest, OverlongOrBinaryIdsAreRejectedWithoutEchoingThem) {
  const std::string long_id(8000, 'j');
  v1::GetJobRequest get;
  get.set_job_id(long_id);
  v1::JobStatus status;
  grpc::Status st = live_->render->GetJob(Ctx().get(), get, &status);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_EQ(st.error_message(), "job_id: longer than 128 bytes");
  get.set_job_id("job-\n\x1b[31m");
  st = live_->render->GetJob(Ctx().get(), get, &status);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
  EXPECT_EQ(st.error_message().find('\n'), std::string::npos) << st.error_message();
  EXPECT_EQ(st.error_message().find('\x1b'), std::string::npos) << st.error_message();
  get.set_job_id("job-" + std::string(100, 'f'));  // well-formed, unknown: NOT_FOUND, echo cut
  st = live_->render->GetJob(Ctx().get(), get, &status);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::NOT_FOUND) << st.error_message();
  EXPECT_LT(st.error_message().size(), 120u) << st.error_message();

  v1::ExtendLeaseRequest extend;
  extend.set_lease_id(std::string(1 << 20, 'l'));
  v1::ExtendLeaseResponse extended;
  st = live_->worker->ExtendLease(Ctx().get(), extend, &extended);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message().substr(0, 200);
  EXPECT_EQ(st.error_message(), "lease_id: longer than 128 bytes");
  v1::LeaseTaskRequest lease;
  lease.set_worker_id("w\nforged");
  v1::LeaseTaskResponse leased;
  st = live_->worker->LeaseTask(Ctx().get(), lease, &leased);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << st.error_message();
}

using TokenTest = testing::TokenCoordinatorTest;

// Auth is checked by gRPC for every call (server/rpc/auth.h), per role: the client token opens
// RenderService only, the worker token WorkerService only; the other role's token is
// PERMISSION_DENIED, no or a wrong token UNAUTHENTICATED.
TEST_F(TokenTest, EachServiceRequiresItsRolesToken) {
  for (const std::string& token :
       {std::string(), std::string("wrong"), std::string("client-token"), std::string("worker-token")}) {
    SCOPED_TRACE(token.empty() ? "no token" : token);
    auto expect_for = [&](const std::string& right, const std::string& other) {
      return [&token, right, other](const grpc::Status& st) {
        if (token == right) {
          EXPECT_NE(st.error_code(), grpc::StatusCode::UNAUTHENTICATED) << st.error_message();
          EXPECT_NE(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
        } else if (token == other) {
          EXPECT_EQ(st.error_code(), grpc::StatusCode::PERMISSION_DENIED) << st.error_message();
        } else {
          EXPECT_EQ(st.error_code(), grpc::StatusCode::UNAUTHENTICATED) << st.error_message();
        }
      };
    };
    const auto expect = expect_for("client-token", "worker-token");
    const auto expect_worker = expect_for("worker-token", "client-token");
    v1::ListJobsResponse list;
    expect(live_->render->ListJobs(Ctx(token).get(), v1::ListJobsRequest(), &list));
    v1::SubmitJobResponse submit;
    expect(live_->render->SubmitJob(Ctx(token).get(), v1::SubmitJobRequest(), &submit));
    v1::UploadSceneResponse upload;
    expect(live_->render->UploadScene(Ctx(token).get(), v1::UploadSceneRequest(), &upload));
    v1::LeaseTaskRequest lease_req;
    lease_req.set_worker_id("w");
    lease_req.set_worker_version(PF_VERSION);
    v1::LeaseTaskResponse lease;
    expect_worker(live_->worker->LeaseTask(Ctx(token).get(), lease_req, &lease));
    v1::ExtendLeaseRequest extend_req;
    extend_req.set_lease_id("x");
    v1::ExtendLeaseResponse extend;
    expect_worker(live_->worker->ExtendLease(Ctx(token).get(), extend_req, &extend));
    v1::CompleteTaskRequest complete_req;
    complete_req.set_lease_id("x");
    v1::CompleteTaskResponse complete;
    expect_worker(live_->worker->CompleteTask(Ctx(token).get(), complete_req, &complete));
    v1::FailTaskRequest fail_req;
    fail_req.set_lease_id("x");
    v1::FailTaskResponse fail;
    expect_worker(live_->worker->FailTask(Ctx(token).get(), fail_req, &fail));
    {
      auto ctx = Ctx(token);
      v1::FetchSceneRequest req;
      req.set_scene_hash(std::string(64, 'c'));
      auto reader = live_->worker->FetchScene(ctx.get(), req);
      v1::SceneFile file;
      while (reader->Read(&file)) {
      }
      expect_worker(reader->Finish());
    }
    {
      auto ctx = Ctx(token);
      v1::WatchJobRequest req;
      req.set_job_id("job-1");
      auto reader = live_->render->WatchJob(ctx.get(), req);
      v1::JobUpdate u;
      while (reader->Read(&u)) {
      }
      expect(reader->Finish());
    }
  }
}

TEST_F(TokenTest, HealthCheckIsOpen) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  grpc::ByteBuffer response;
  // grpc.health.v1.Health/Check with an empty HealthCheckRequest (service "").
  grpc::GenericStub stub(live_->channel);
  const grpc::Slice empty;
  grpc::ByteBuffer req(&empty, 1);
  const grpc::Status status =
      test_util::BlockingGenericCall(stub, &ctx, "/grpc.health.v1.Health/Check", &req, &response);
  EXPECT_TRUE(status.ok()) << status.error_message();
  std::vector<grpc::Slice> slices;
  ASSERT_TRUE(response.Dump(&slices).ok());
  std::string bytes;
  for (const auto& s : slices) bytes.append(reinterpret_cast<const char*>(s.begin()), s.size());
  EXPECT_EQ(bytes, std::string("\x08\x01", 2)) << "status: SERVING";
}

}  // namespace
}  // namespace pf::server
