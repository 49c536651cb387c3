// Admission of a validated job through the JobStore interface (server/scheduling/job_submission.h):
// the row is stored before the job is scheduled, and a job whose row cannot be stored is never
// scheduled (docs/farm.md, "Durability"). The store here is an in-memory JobStore, which is the
// point of the interface: scheduling knows no SQLite.

#include "server/scheduling/job_submission.h"

#include <gtest/gtest.h>

#include <cerrno>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/core/error.h"
#include "server/clock.h"
#include "server/scheduling/scheduler.h"
#include "server/store/job_store.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
namespace v1 = photonfarm::v1;
using testing::MakeConfig;
using testing::MultipleMaps;

// Keeps inserted rows in memory; `full` makes every write fail as a full disk does.
class MemoryJobStore final : public JobStore {
 public:
  bool full = false;
  std::vector<JobRow> jobs;
  // Set when InsertJob runs: how many jobs the scheduler already had then.
  Scheduler* scheduler = nullptr;
  size_t scheduled_at_insert = ~size_t(0);

  void InsertJob(const JobRow& job, const std::vector<TaskRow>&) override {
    if (scheduler) scheduled_at_insert = scheduler->List(/*include_finished=*/true).size();
    if (full) throw StorageError("INSERT INTO jobs: database or disk is full", ENOSPC);
    jobs.push_back(job);
  }
  void Apply(const std::vector<JobRow>&, const std::vector<TaskRow>&) override {
    throw std::logic_error("not used by admission");
  }
  void UpdateJobSpec(const std::string&, const std::string&) override {
    throw std::logic_error("not used by admission");
  }
  std::vector<JobRow> LoadJobs() override { return jobs; }
  std::vector<TaskRow> LoadTasks(const std::string&) override { return {}; }
  uint64_t CountTasks(const std::string&, TaskState) override { return 0; }
  void DeleteJob(const std::string&) override { throw std::logic_error("not used by admission"); }
  void SetJobPaused(const std::string&, bool) override { throw std::logic_error("not used by admission"); }
};

class JobSubmissionTest : public ::testing::Test {
 protected:
  JobSubmissionTest() : scheduler_(clock_, SchedulerOptions{.lease_seconds = 30, .max_attempts = 3}) {
    store_.scheduler = &scheduler_;
  }
  FakeClock clock_;
  Scheduler scheduler_;
  MemoryJobStore store_;
};

TEST_F(JobSubmissionTest, TheRowIsStoredBeforeTheJobIsScheduled) {
  JobConfig config = MakeConfig(MultipleMaps(2, 0), 8, 4, /*priority=*/3);
  const std::string id = SubmitValidatedJob(scheduler_, store_, config, "alice");

  ASSERT_EQ(store_.jobs.size(), 1u);
  const JobRow& row = store_.jobs[0];
  EXPECT_EQ(row.job_id, id);
  EXPECT_EQ(row.state, JobState::kQueued);
  v1::JobSpec stored;
  ASSERT_TRUE(stored.ParseFromString(row.spec));
  EXPECT_EQ(stored.scene_hash(), config.spec.scene_hash());
  EXPECT_EQ(stored.priority(), 3);
  // The stored spec is the one the job echoes: a restarted coordinator resumes what was accepted.
  EXPECT_EQ(stored.SerializeAsString(), scheduler_.Status(id).spec().SerializeAsString());
  EXPECT_EQ(store_.scheduled_at_insert, 0u) << "the job was scheduled before its row was stored";
  EXPECT_EQ(scheduler_.Status(id).state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(scheduler_.Status(id).tasks_total(), 2u);
}

TEST_F(JobSubmissionTest, AJobWhoseRowCannotBeStoredIsNeverScheduled) {
  store_.full = true;
  EXPECT_THROW(SubmitValidatedJob(scheduler_, store_, MakeConfig(MultipleMaps(2, 0), 8, 4), "alice"),
               StorageError);
  EXPECT_TRUE(scheduler_.List(/*include_finished=*/true).empty());
  EXPECT_FALSE(scheduler_.TryLease({"w1", {}}).has_value()) << "a task of an unstored job was leased";
}

}  // namespace
}  // namespace pf::server
