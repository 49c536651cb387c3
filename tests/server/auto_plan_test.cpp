// SubmitJob with `plan.auto_plan` against a real coordinator: the chosen plan replaces it in the
// stored spec (echoed by GetJob with chosen_by_auto), photons become photons per map, the
// choice follows the scene's caustic paths; invalid requests are INVALID_ARGUMENT naming the field.
#include <gtest/gtest.h>

#include "tests/server/server_test_util.h"
#include "tests/util/job_specs.h"

namespace pf::server {
namespace {
using testing::Ctx;
namespace v1 = photonfarm::v1;

class AutoPlanTest : public testing::LiveCoordinatorTest {
 protected:
  v1::JobSpec AutoSpec(uint32_t workers, uint32_t spp, uint64_t budget) {
    v1::JobSpec spec = test_util::CornellPhotonMapSpec(hash_, 64, 64, 1, 9);
    spec.mutable_plan()->mutable_auto_plan()->set_workers(workers);
    spec.mutable_plan()->mutable_auto_plan()->set_samples_per_pixel(spp);
    spec.mutable_settings()->mutable_photon_map()->set_photons(budget);
    return spec;
  }
  grpc::Status Submit(const v1::JobSpec& spec, std::string* job_id) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = spec;
    v1::SubmitJobResponse resp;
    const grpc::Status st = live_->render->SubmitJob(Ctx().get(), req, &resp);
    *job_id = resp.job_id();
    return st;
  }
  v1::JobStatus Get(const std::string& id) {
    v1::GetJobRequest req;
    req.set_job_id(id);
    v1::JobStatus status;
    EXPECT_TRUE(live_->render->GetJob(Ctx().get(), req, &status).ok());
    return status;
  }
};

TEST_F(AutoPlanTest, TheChosenPlanIsStoredAndReported) {
  std::string id;
  ASSERT_TRUE(Submit(AutoSpec(3, 4, 640000), &id).ok());
  const v1::JobStatus s = Get(id);
  const v1::Plan& plan = s.spec().plan();
  // The Cornell box has no specular surface: skipping; 3 workers want 12 tasks: S 4, 1 round.
  ASSERT_TRUE(plan.has_skipping()) << plan.DebugString();
  EXPECT_FALSE(plan.has_auto_plan());
  EXPECT_EQ(plan.skipping().stride(), 4u);
  EXPECT_EQ(plan.skipping().rounds(), 1u);
  EXPECT_EQ(plan.skipping().samples_per_pixel(), 4u);
  ASSERT_TRUE(plan.has_chosen_by_auto());
  EXPECT_EQ(plan.chosen_by_auto().workers(), 3u);
  EXPECT_EQ(plan.chosen_by_auto().photon_budget(), 640000u);
  EXPECT_EQ(plan.chosen_by_auto().photons_per_map(), 40000u);
  EXPECT_FALSE(plan.chosen_by_auto().caustic_map());
  EXPECT_FALSE(plan.chosen_by_auto().maps_can_be_shipped());
  EXPECT_EQ(s.spec().settings().photon_map().photons(), 40000u);
  EXPECT_EQ(s.tasks_total(), 16u);
  EXPECT_NE(plan.chosen_by_auto().reason().find("skipping S 4 x 1 rounds"), std::string::npos)
      << plan.chosen_by_auto().reason();
}

TEST_F(AutoPlanTest, ACausticMapMakesItMultipleMaps) {
  v1::JobSpec spec = AutoSpec(2, 4, 640000);
  spec.mutable_settings()->mutable_photon_map()->set_caustic(v1::CAUSTIC_MODE_ON);
  std::string id;
  ASSERT_TRUE(Submit(spec, &id).ok());
  const v1::JobStatus status = Get(id);
  const v1::Plan& plan = status.spec().plan();
  ASSERT_TRUE(plan.has_multiple_maps()) << plan.DebugString();
  EXPECT_EQ(plan.multiple_maps().maps(), 2u);
  EXPECT_EQ(plan.multiple_maps().samples_per_pixel(), 2u);
  EXPECT_TRUE(plan.chosen_by_auto().caustic_map());
  EXPECT_EQ(plan.chosen_by_auto().photons_per_map(), 320000u);
}

TEST_F(AutoPlanTest, InvalidAutoRequestsNameTheField) {
  std::string id;
  grpc::Status st = Submit(AutoSpec(1, 0, 1000), &id);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("spec.plan.auto_plan.samples_per_pixel", 0), 0u) << st.error_message();
  st = Submit(AutoSpec(1, 4, 0), &id);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("spec.settings.photon_map.photons", 0), 0u) << st.error_message();
  // The resolved spec is validated as any other.
  v1::JobSpec spec = AutoSpec(1, 4, 100000);
  spec.mutable_stop()->set_time_budget_seconds(-1);
  st = Submit(spec, &id);
  EXPECT_EQ(st.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(st.error_message().rfind("spec.stop.time_budget_seconds", 0), 0u) << st.error_message();
}

}  // namespace
}  // namespace pf::server
