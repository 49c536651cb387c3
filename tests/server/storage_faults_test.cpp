// The fault-injection suite of the coordinator's storage (docs/farm.md, "Durability"). Every write
// site — the result journal (write, fdatasync, truncate, unlink), the checkpoint (open, write,
// fsync, close, rename, the directory's fsync) and the SQLite database (write, sync) — fails with
// ENOSPC or EIO, once or until the "disk" is freed, early or late in a job, with or without a
// crash while it fails. In every case:
//   - a result acknowledged as stored is still merged after a crash and a restart (never re-run),
//   - recovery finds no lost acknowledged result and no damaged journal,
//   - the job ends SUCCEEDED with an image bit-identical to a run without faults, and a SUCCEEDED
//     job served after a restart serves exactly that image — never a wrong image called a success.
// Named tests below reproduce the defects a hostile test found, one each.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>

#include "common/core/atomic_file.h"
#include "server/rpc/job_images.h"
#include "server/rpc/status_mapping.h"
#include "server/scheduling/recovery.h"
#include "server/scheduling/scheduler.h"
#include "server/store/checkpoint.h"
#include "server/store/journal.h"
#include "server/store/persister.h"
#include "server/store/sqlite_store.h"
#include "tests/server/faulty_storage.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using testing::FakeCatalog;
using testing::FaultInjector;
using testing::FaultRule;
using testing::FaultyFiles;
using testing::FaultySqlite;
using testing::FileOp;
using ::testing::HasSubstr;
using testing::SkippingSpec;
using testing::SyntheticResult;
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

// Every case writes through real system calls; on tmpfs (when there is one) they cost nothing.
fs::path ScratchRoot() {
  std::error_code ec;
  return fs::is_directory("/dev/shm", ec) ? fs::path("/dev/shm") : fs::temp_directory_path();
}

// The job of every case: 24 tasks (stride 2: 4 pixel sets × 6 rounds) of a 12 × 10 image.
JobConfig CaseJob(const SceneCatalog& catalog) {
  return ValidateJobSpec(SkippingSpec(2, 6), catalog);
}

// The image of the job without faults, crashes or persistence.
ResolvedImage ReferenceImage(const JobConfig& config, const Clock& clock) {
  Scheduler scheduler(clock, {});
  std::unique_ptr<Job> job = scheduler.PrepareJob(config);
  const std::string id = job->id();
  scheduler.AddJob(std::move(job));
  while (std::optional<Lease> l = scheduler.TryLease({"w", {}}))
    EXPECT_EQ(scheduler.Complete(l->lease_id, l->worker_id, SyntheticResult(l->task, 12, 10)).status,
              CompleteStatus::kMerged);
  return *scheduler.Snapshot(id, true).image;
}

void ExpectSameImage(const ResolvedImage& got, const ResolvedImage& want) {
  ASSERT_EQ(got.image.size(), want.image.size());
  EXPECT_EQ(got.samples_merged, want.samples_merged);
  for (size_t p = 0; p < want.image.size(); ++p)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(got.image[p][c], want.image[p][c]) << "pixel " << p;
}

// A coordinator's storage in a folder that outlives its crashes, and the job's workers.
class StorageCase {
 public:
  StorageCase() : dir_("pf_storage_faults", ScratchRoot()) {}

  // A coordinator over the folder; `files` (null: the real calls) carries the journal and
  // checkpoint writes.
  struct Run {
    std::unique_ptr<SqliteStore> db;
    std::unique_ptr<Scheduler> scheduler;
    std::unique_ptr<Persister> persister;
    RecoveryReport report;
  };
  Run Start(FileLayer* files) {
    Run run;
    run.db = std::make_unique<SqliteStore>(dir_.path() / "coordinator.db");
    run.scheduler = std::make_unique<Scheduler>(clock_, SchedulerOptions{});
    run.report = RecoverJobs(*run.db, catalog_, cp_dir(), *run.scheduler, clock_);
    run.persister = std::make_unique<Persister>(*run.scheduler, *run.db, cp_dir(), clock_, /*interval=*/0,
                                                files ? *files : SystemFiles());
    return run;
  }
  std::string Submit(Run& run) { return testing::SubmitStored(*run.scheduler, *run.db, CaseJob(catalog_)); }

  // One worker's turn: lease, merge, journal; the ack's answer is recorded. False if no task.
  bool RenderOne(Run& run) {
    const std::optional<Lease> lease = run.scheduler->TryLease({"w", {}});
    if (!lease) return false;
    const std::vector<float> sums = SyntheticResult(lease->task, 12, 10);
    const CompleteResult result = run.scheduler->Complete(lease->lease_id, lease->worker_id, sums);
    EXPECT_EQ(result.status, CompleteStatus::kMerged);
    rendered_.push_back(lease->task_id);
    run.persister->JournalThenAck(lease->job_id, lease->task_id, result.epoch, result.merge_seq, sums,
                                  [this, task = lease->task_id](const std::string& not_stored) {
                                    if (not_stored.empty())
                                      acknowledged_.insert(task);
                                    else
                                      ++not_acknowledged_;
                                  });
    return true;
  }

  const JobConfig config() const { return CaseJob(catalog_); }
  const Clock& clock() const { return clock_; }
  fs::path cp_dir() const { return dir_.path() / "checkpoints"; }
  const std::set<uint64_t>& acknowledged() const { return acknowledged_; }
  uint64_t not_acknowledged() const { return not_acknowledged_; }
  std::vector<uint64_t>& rendered() { return rendered_; }

 private:
  test_util::TempDir dir_;
  FakeClock clock_;
  FakeCatalog catalog_;
  std::set<uint64_t> acknowledged_;
  uint64_t not_acknowledged_ = 0;
  std::vector<uint64_t> rendered_;
};

struct Site {
  const char* name;
  FileOp op;
  const char* path_part;
  bool at_end = false;
  bool torn = false;
};
const Site kSites[] = {
    {"journal_write", FileOp::kWrite, ".journal", false, true},
    {"journal_fdatasync", FileOp::kFdatasync, ".journal"},
    {"journal_truncate", FileOp::kFtruncate, ".journal"},
    {"journal_unlink", FileOp::kUnlink, ".journal"},
    {"checkpoint_open", FileOp::kOpen, ".acc.tmp-"},
    {"checkpoint_write", FileOp::kWrite, ".acc.tmp-", false, true},
    {"checkpoint_fsync", FileOp::kFsync, ".acc.tmp-"},
    {"checkpoint_close", FileOp::kClose, ".acc.tmp-"},
    {"checkpoint_rename", FileOp::kRename, ".acc", true},
    {"directory_fsync", FileOp::kFsync, "/checkpoints", true},
    {"data_dir_writes", FileOp::kWrite, "checkpoints/", false, true},  // journal and checkpoint at once
    {"sqlite_write", FileOp::kSqliteWrite, "coordinator.db", false, true},
    {"sqlite_sync", FileOp::kSqliteSync, "coordinator.db"},
};

enum class Span { kOnce, kUntilFreed };
struct FaultCase {
  Site site;
  Span span;
  int error;
  uint64_t first_call;
  bool crash;
};

std::string Describe(const FaultCase& c) {
  return std::string(c.site.name) + (c.span == Span::kOnce ? "_once" : "_until_freed") +
         (c.error == ENOSPC ? "_enospc" : "_eio") + "_call" + std::to_string(c.first_call) +
         (c.crash ? "_crash" : "");
}
std::string CaseName(const ::testing::TestParamInfo<FaultCase>& info) {
  return Describe(info.param);
}
void PrintTo(const FaultCase& c, std::ostream* os) {
  *os << Describe(c);
}

std::vector<FaultCase> AllCases() {
  std::vector<FaultCase> out;
  for (const Site& site : kSites)
    for (Span span : {Span::kOnce, Span::kUntilFreed})
      for (int error : {ENOSPC, EIO})
        for (uint64_t first : {uint64_t(1), uint64_t(3)})
          for (bool crash : {false, true})
            if (first == 1 || site.op != FileOp::kUnlink)  // the journal is removed once, at the end
              out.push_back({site, span, error, first, crash});
  return out;
}

class StorageFaults : public ::testing::TestWithParam<FaultCase> {};

TEST_P(StorageFaults, EndInTheRightImageAndKeepEveryAcknowledgedResult) {
  const FaultCase& c = GetParam();
  StorageCase storage;
  const ResolvedImage reference = ReferenceImage(storage.config(), storage.clock());
  FaultInjector faults;
  FaultyFiles files(faults);
  std::optional<FaultySqlite> sqlite;
  if (c.site.op == FileOp::kSqliteWrite || c.site.op == FileOp::kSqliteSync) sqlite.emplace(faults);

  // Phase 1: the job runs while the site fails; the "disk" is freed after 4 more results, or
  // when the job can go no further; with `crash`, the coordinator dies 2 results after the first
  // failure (no final flush: what a kill -9 leaves).
  std::string id;
  bool crashed = false;
  {
    StorageCase::Run run = storage.Start(&files);
    id = storage.Submit(run);
    faults.Arm(FaultRule{c.site.op, c.site.path_part, c.site.at_end, c.first_call,
                         c.span == Span::kOnce ? 1 : FaultRule::kUntilDisarmed, c.error, c.site.torn});
    int since_fault = -1, idle = 0;
    for (int turn = 0; turn < 200; ++turn) {
      if (faults.failures() > 0) ++since_fault;
      if (c.crash && since_fault == 2) {
        run.persister->Abandon();
        crashed = true;
        break;
      }
      if (since_fault >= 4) faults.Disarm();
      if (!storage.RenderOne(run)) {
        const v1::JobStatus s = run.scheduler->Status(id);
        if (s.state() == v1::JOB_STATE_SUCCEEDED) break;
        // Paused for storage (its results could be stored nowhere): the operator frees space.
        EXPECT_TRUE(s.paused_for_storage()) << s.ShortDebugString();
        faults.Disarm();
        ASSERT_LT(++idle, 10) << "the job does not resume after the disk is freed";
      }
      run.persister->FlushNow(/*checkpoints_due=*/turn % 5 == 4);
    }
    ASSERT_TRUE(crashed || run.scheduler->Status(id).state() == v1::JOB_STATE_SUCCEEDED);
    if (!crashed) {
      faults.Disarm();
      EXPECT_TRUE(run.persister->Stop()) << "with space again, the final flush stores everything";
    }
  }
  faults.Disarm();
  EXPECT_GT(faults.failures(), 0u) << "the site was never reached: the case tests nothing";
  const std::set<uint64_t> acknowledged = storage.acknowledged();

  // Phase 2: restart (real system calls), finish the job, stop.
  std::vector<uint64_t> rerun;
  {
    StorageCase::Run run = storage.Start(nullptr);
    EXPECT_EQ(run.report.acknowledged_lost, 0u) << "an acknowledged result was not stored";
    EXPECT_EQ(run.report.journals_damaged, 0u);
    EXPECT_EQ(run.report.jobs_rerendered, 0u) << "a finished job's final image failed its seal";
    const size_t before = storage.rendered().size();
    while (storage.RenderOne(run)) run.persister->FlushNow(false);
    rerun.assign(storage.rendered().begin() + int64_t(before), storage.rendered().end());
    EXPECT_EQ(run.scheduler->Status(id).state(), v1::JOB_STATE_SUCCEEDED);
    EXPECT_TRUE(run.persister->Stop());
  }
  for (uint64_t task : rerun) {
    EXPECT_FALSE(acknowledged.count(task)) << "task " << task << " was acknowledged, then re-run";
  }
  if (!crashed) {
    EXPECT_TRUE(rerun.empty()) << "nothing is lost without a crash";
  }

  // Phase 3: a SUCCEEDED job read back from disk serves exactly the right image.
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.jobs_finished, 1u);
  v1::JobStatus status;
  ExpectSameImage(ResolveJobImage(*run.scheduler, id, &status), reference);
  EXPECT_EQ(status.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(status.tasks_done(), 24u);
}

INSTANTIATE_TEST_SUITE_P(EveryWriteSite, StorageFaults, ::testing::ValuesIn(AllCases()), CaseName);

// --- One test per defect of the hostile test ---

// A full disk at the final checkpoint: the final row was written SUCCEEDED anyway, recovery then
// dropped the journal and served an older checkpoint (10 of 32 tasks, exit 0). Now the final row
// waits for the final checkpoint, the coordinator reports the failed final flush, and after a
// restart the job completes from its journal.
TEST(StorageDefects, AFullDiskAtTheFinalCheckpointNeverLeavesASucceededRowWithAWrongImage) {
  StorageCase storage;
  const ResolvedImage reference = ReferenceImage(storage.config(), storage.clock());
  FaultInjector faults;
  FaultyFiles files(faults);
  std::string id;
  {
    StorageCase::Run run = storage.Start(&files);
    id = storage.Submit(run);
    for (int i = 0; i < 10; ++i) storage.RenderOne(run);
    run.persister->FlushNow(true);  // an early checkpoint of 10 tasks
    faults.Arm({FileOp::kOpen, ".acc.tmp-", false, 1, FaultRule::kUntilDisarmed, ENOSPC});
    while (storage.RenderOne(run)) run.persister->FlushNow(false);
    EXPECT_EQ(run.scheduler->Status(id).state(), v1::JOB_STATE_SUCCEEDED) << "in memory";
    EXPECT_THAT(run.scheduler->Status(id).storage_error(), HasSubstr("No space left on device"));
    EXPECT_EQ(storage.acknowledged().size(), 24u) << "the journal took every result";
    EXPECT_FALSE(run.persister->Stop()) << "the final checkpoint could not be stored: pf-coordinator exits 1";
  }
  SqliteStore db(storage.cp_dir().parent_path() / "coordinator.db");
  const std::vector<JobRow> rows = db.LoadJobs();
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].state, JobState::kRunning) << "no final row without its final checkpoint";
  faults.Disarm();
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.tasks_from_journal, 14u);
  EXPECT_EQ(run.report.acknowledged_lost, 0u);
  EXPECT_FALSE(storage.RenderOne(run)) << "nothing is re-run";
  run.persister->FlushNow(true);
  ExpectSameImage(ResolveJobImage(*run.scheduler, id, nullptr), reference);
  EXPECT_EQ(run.scheduler->Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// ENOSPC on the journal append and on the checkpoint: workers were told merged = true for all 32
// results while 10 were journaled; after kill -9, 22 acknowledged tasks were re-run. Now a result
// stored nowhere is answered "not stored" and its job pauses until it can be stored.
TEST(StorageDefects, ResultsThatCannotBeStoredAreNeverAcknowledgedAndTheJobPauses) {
  StorageCase storage;
  FaultInjector faults;
  FaultyFiles files(faults);
  StorageCase::Run run = storage.Start(&files);
  const std::string id = storage.Submit(run);
  for (int i = 0; i < 3; ++i) {
    storage.RenderOne(run);
    run.persister->FlushNow(false);
  }
  ASSERT_EQ(storage.acknowledged().size(), 3u);
  // Every write fails: the journal's and the checkpoint's.
  faults.Arm({FileOp::kWrite, "checkpoints/", false, 1, FaultRule::kUntilDisarmed, ENOSPC, /*torn=*/true});
  ASSERT_TRUE(storage.RenderOne(run));
  run.persister->FlushNow(false);
  EXPECT_EQ(storage.acknowledged().size(), 3u) << "not acknowledged";
  EXPECT_EQ(storage.not_acknowledged(), 1u);
  const v1::JobStatus paused = run.scheduler->Status(id);
  EXPECT_TRUE(paused.paused_for_storage());
  EXPECT_THAT(paused.storage_error(), HasSubstr("No space left on device"));
  EXPECT_FALSE(storage.RenderOne(run)) << "no new leases while nothing can be stored";
  faults.Disarm();
  run.persister->FlushNow(false);  // the retried checkpoint stores it
  EXPECT_FALSE(run.scheduler->Status(id).paused_for_storage());
  EXPECT_EQ(run.scheduler->Status(id).storage_error(), "");
  EXPECT_TRUE(storage.RenderOne(run)) << "resumed";
}

// The same with a crash while nothing can be stored: the unacknowledged result is re-run, and
// recovery does not mistake it for a lost acknowledged one (its DONE row was never written).
TEST(StorageDefects, AResultStoredNowhereIsReRunAfterACrashWithoutAFalseDataLoss) {
  StorageCase storage;
  FaultInjector faults;
  FaultyFiles files(faults);
  std::string id;
  uint64_t unstored = 0;
  {
    StorageCase::Run run = storage.Start(&files);
    id = storage.Submit(run);
    storage.RenderOne(run);
    run.persister->FlushNow(false);
    faults.Arm({FileOp::kWrite, "checkpoints/", false, 1, FaultRule::kUntilDisarmed, ENOSPC, /*torn=*/true});
    storage.RenderOne(run);
    unstored = storage.rendered().back();
    run.persister->FlushNow(false);
    run.persister->FlushNow(true);  // rows of the DONE task are not written while it is unstored
    run.persister->Abandon();
  }
  faults.Disarm();
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.acknowledged_lost, 0u);
  EXPECT_EQ(run.report.tasks_merged, 1u);
  ASSERT_TRUE(storage.RenderOne(run));
  EXPECT_EQ(storage.rendered().back(), unstored) << "the unstored result is the first re-run";
}

// A torn journal append (the disk filled in the middle of an entry) followed by good appends read
// as damage: the later, acknowledged entries were unreadable and the job was reported DATA_LOSS.
TEST(StorageDefects, ATornAppendIsCutOffSoTheEntriesAfterItStayReadable) {
  StorageCase storage;
  FaultInjector faults;
  FaultyFiles files(faults);
  std::string id;
  {
    StorageCase::Run run = storage.Start(&files);
    id = storage.Submit(run);
    storage.RenderOne(run);
    run.persister->FlushNow(false);
    faults.Arm({FileOp::kWrite, ".journal", false, 1, 1, ENOSPC, /*torn=*/true});
    storage.RenderOne(run);  // torn, then checkpointed instead
    run.persister->FlushNow(false);
    for (int i = 0; i < 3; ++i) {
      storage.RenderOne(run);
      run.persister->FlushNow(false);
    }
    run.persister->Abandon();
  }
  uint64_t valid = 0;
  bool damaged = false;
  const auto entries = ReadJournalFile(Persister::JournalFile(storage.cp_dir(), id), &valid, &damaged);
  EXPECT_FALSE(damaged);
  EXPECT_EQ(entries.size(), 3u) << "the three appends after the checkpoint";
  EXPECT_EQ(valid, fs::file_size(Persister::JournalFile(storage.cp_dir(), id))) << "no torn bytes left";
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.journals_damaged, 0u);
  EXPECT_EQ(run.report.tasks_merged, 5u);
  EXPECT_EQ(storage.acknowledged().size(), 5u);
}

// An older, valid checkpoint of a finished job put back in place was served as its image
// (SUCCEEDED, exit 0, 7 of 96 tasks). Now the image must carry the seal in the job's row: served,
// it is DATA_LOSS; after a restart the job is rendered again and ends in the right image.
TEST(StorageDefects, AnOlderCheckpointOfAFinishedJobIsNeverServedAsItsImage) {
  StorageCase storage;
  const ResolvedImage reference = ReferenceImage(storage.config(), storage.clock());
  const fs::path old_copy = storage.cp_dir().parent_path() / "old.acc";
  std::string id;
  {
    StorageCase::Run run = storage.Start(nullptr);
    id = storage.Submit(run);
    for (int i = 0; i < 7; ++i) storage.RenderOne(run);
    run.persister->FlushNow(true);
    fs::copy_file(Persister::CheckpointFile(storage.cp_dir(), id), old_copy);
    while (storage.RenderOne(run)) run.persister->FlushNow(false);
    EXPECT_TRUE(run.persister->Stop());
    fs::copy_file(old_copy, Persister::CheckpointFile(storage.cp_dir(), id),
                  fs::copy_options::overwrite_existing);
    const grpc::Status served = StatusFromException(
        [&] {
          try {
            EncodeJobImage(*run.scheduler, id);
          } catch (...) {
            return std::current_exception();
          }
          return std::exception_ptr();
        }(),
        "GetImage");
    EXPECT_EQ(served.error_code(), grpc::StatusCode::DATA_LOSS);
    EXPECT_THAT(served.error_message(), HasSubstr("holds 7 tasks, 24 expected"));
  }
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.jobs_rerendered, 1u);
  EXPECT_NE(run.scheduler->Status(id).state(), v1::JOB_STATE_SUCCEEDED) << "no longer final";
  EXPECT_TRUE(fs::exists(Persister::CheckpointFile(storage.cp_dir(), id).string() + ".damaged"));
  while (storage.RenderOne(run)) run.persister->FlushNow(false);
  EXPECT_TRUE(run.persister->Stop());
  ExpectSameImage(ResolveJobImage(*run.scheduler, id, nullptr), reference);
  EXPECT_EQ(run.scheduler->Status(id).state(), v1::JOB_STATE_SUCCEEDED);
}

// A journal cut short after its results were acknowledged (truncation, not a torn tail) was only a
// warning. A DONE row names a stored result, so recovery sees the loss: DATA LOSS, the tasks re-run.
TEST(StorageDefects, AcknowledgedResultsLostFromTheJournalAreReportedAsDataLoss) {
  StorageCase storage;
  const ResolvedImage reference = ReferenceImage(storage.config(), storage.clock());
  std::string id;
  {
    StorageCase::Run run = storage.Start(nullptr);
    id = storage.Submit(run);
    for (int i = 0; i < 6; ++i) {
      storage.RenderOne(run);
      run.persister->FlushNow(false);
    }
    run.persister->Abandon();
  }
  const fs::path journal = Persister::JournalFile(storage.cp_dir(), id);
  fs::resize_file(journal, fs::file_size(journal) / 2);
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.acknowledged_lost, 3u);
  EXPECT_EQ(run.report.tasks_from_journal, 3u);
  while (storage.RenderOne(run)) run.persister->FlushNow(false);
  run.persister->FlushNow(true);
  ExpectSameImage(ResolveJobImage(*run.scheduler, id, nullptr), reference);
}

// --- Convictions across crashes (docs/farm.md, "Result verification") ---

// Results of a convicted worker never come back from the files: once the restart's empty
// checkpoint (epoch 1) and the job's row are stored, a crash and a restart keep the job at epoch 1,
// replay none of the epoch-0 journal entries and keep the convicted worker off the job.
TEST(StorageConvictions, AStoredRestartSurvivesACrashWithoutItsConvictedResults) {
  StorageCase storage;
  const ResolvedImage reference = ReferenceImage(storage.config(), storage.clock());
  FaultInjector faults;
  FaultyFiles files(faults);
  std::string id;
  {
    StorageCase::Run run = storage.Start(&files);
    id = storage.Submit(run);
    for (int i = 0; i < 4; ++i) storage.RenderOne(run);
    run.persister->FlushNow(false);  // journaled, epoch 0
    ASSERT_TRUE(run.scheduler->ConvictWorker(id, "w", 0, "wrong result"));
    // The journal cannot be emptied after the restart's checkpoint: its epoch-0 entries stay.
    faults.Arm({FileOp::kFtruncate, ".journal", false, 1, FaultRule::kUntilDisarmed, EIO});
    faults.Arm({FileOp::kUnlink, ".journal", false, 1, FaultRule::kUntilDisarmed, EIO});
    run.persister->FlushNow(false);
    run.persister->Abandon();
  }
  uint64_t valid = 0;
  EXPECT_EQ(ReadJournalFile(Persister::JournalFile(storage.cp_dir(), id), &valid).size(), 4u)
      << "the old entries are still there";
  faults.Disarm();
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.report.tasks_merged, 0u) << "no epoch-0 result comes back";
  EXPECT_EQ(run.report.acknowledged_lost, 0u);
  EXPECT_EQ(run.scheduler->JobEpoch(id), 1u);
  EXPECT_FALSE(storage.RenderOne(run)) << "the convicted worker 'w' stays off the job";
  while (std::optional<Lease> l = run.scheduler->TryLease({"honest", {}})) {
    const std::vector<float> sums = SyntheticResult(l->task, 12, 10);
    const CompleteResult r = run.scheduler->Complete(l->lease_id, l->worker_id, sums);
    run.persister->JournalThenAck(id, l->task_id, r.epoch, r.merge_seq, sums, [](const std::string&) {});
    run.persister->FlushNow(false);
  }
  EXPECT_TRUE(run.persister->Stop());
  ExpectSameImage(ResolveJobImage(*run.scheduler, id, nullptr), reference);
}

// A conviction's restart is stored as a checkpoint (the empty image) and a row; the coordinator
// died when only one of them had reached the disk (the other's write failed: full). Either carries
// the epoch and the convicted workers: the old results stay out and the convicted worker stays off
// the job.
class RestartHalfStored : public ::testing::TestWithParam<FaultRule> {};

TEST_P(RestartHalfStored, KeepsItsEpochAndConvictions) {
  StorageCase storage;
  FaultInjector faults;
  FaultyFiles files(faults);
  FaultySqlite sqlite(faults);
  std::string id;
  {
    StorageCase::Run run = storage.Start(&files);
    id = storage.Submit(run);
    for (int i = 0; i < 3; ++i) storage.RenderOne(run);
    run.persister->FlushNow(false);
    ASSERT_TRUE(run.scheduler->ConvictWorker(id, "w", 0, "wrong result"));
    faults.Arm(GetParam());
    EXPECT_FALSE(run.persister->FlushNow(false)) << "one of the two is not stored";
    EXPECT_FALSE(run.scheduler->TryLease({"honest", {}}).has_value()) << "held until both are stored";
    run.persister->Abandon();
  }
  faults.Disarm();
  StorageCase::Run run = storage.Start(nullptr);
  EXPECT_EQ(run.scheduler->JobEpoch(id), 1u);
  EXPECT_EQ(run.report.tasks_merged, 0u) << "no epoch-0 result comes back";
  EXPECT_FALSE(storage.RenderOne(run)) << "the convicted worker 'w' stays off the job";
}

INSTANTIATE_TEST_SUITE_P(
    StorageConvictions, RestartHalfStored,
    ::testing::Values(
        // Only the checkpoint reached the disk.
        FaultRule{FileOp::kSqliteWrite, "coordinator.db", false, 1, FaultRule::kUntilDisarmed, ENOSPC},
        // Only the row reached the disk.
        FaultRule{FileOp::kOpen, ".acc.tmp-", false, 1, FaultRule::kUntilDisarmed, ENOSPC}),
    [](const ::testing::TestParamInfo<FaultRule>& info) {
      return info.param.op == FileOp::kSqliteWrite ? std::string("OnlyTheCheckpoint")
                                                   : std::string("OnlyTheRow");
    });

// The persister flushed between a merge and its JournalThenAck, and that flush's checkpoint holds
// the result; then its journal append fails. It is stored (answered so), and the job is not
// paused — before, it waited for a checkpoint that nothing would write and stayed paused.
TEST(StorageConvictions, AResultACheckpointHoldsAlreadyIsAcknowledgedWhenItsAppendFails) {
  StorageCase storage;
  FaultInjector faults;
  FaultyFiles files(faults);
  StorageCase::Run run = storage.Start(&files);
  const std::string id = storage.Submit(run);
  const std::optional<Lease> l = run.scheduler->TryLease({"w", {}});
  ASSERT_TRUE(l.has_value());
  const std::vector<float> sums = SyntheticResult(l->task, 12, 10);
  const CompleteResult r = run.scheduler->Complete(l->lease_id, l->worker_id, sums);
  run.persister->FlushNow(/*checkpoints_due=*/true);  // holds the result already
  faults.Arm({FileOp::kWrite, "checkpoints/", false, 1, FaultRule::kUntilDisarmed, ENOSPC});
  std::string answer = "not answered";
  run.persister->JournalThenAck(id, l->task_id, r.epoch, r.merge_seq, sums,
                                [&](const std::string& not_stored) { answer = not_stored; });
  run.persister->FlushNow(false);
  EXPECT_EQ(answer, "") << "stored by the earlier checkpoint";
  EXPECT_FALSE(run.scheduler->Status(id).paused_for_storage());
  EXPECT_TRUE(run.scheduler->TryLease({"w", {}}).has_value());
}

}  // namespace
}  // namespace pf::server
