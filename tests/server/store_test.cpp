// Persistence on real files: SQLite rows survive reopening, checkpoint files are atomic and
// self-checking, and a "crash" (objects destroyed without a graceful stop) followed by recovery
// resumes with exactly the checkpointed merged set and ends in the same image as a run without
// the crash.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <fstream>
#include <optional>

#include "common/core/atomic_file.h"
#include "common/core/byte_codec.h"
#include "common/core/error.h"
#include "common/render/progressive_radius.h"
#include "server/clock.h"
#include "server/rpc/job_images.h"
#include "server/rpc/status_mapping.h"
#include "server/scheduling/recovery.h"
#include "server/scheduling/scheduler.h"
#include "server/store/checkpoint.h"
#include "server/store/checksum.h"
#include "server/store/journal.h"
#include "server/store/persister.h"
#include "server/store/sqlite_store.h"
#include "tests/server/faulty_storage.h"
#include "tests/server/server_test_util.h"

namespace pf::server {
namespace {
using ::testing::HasSubstr;
using testing::SyntheticResult;
using testing::TempDir;
namespace fs = std::filesystem;
namespace v1 = photonfarm::v1;

using testing::FakeCatalog;
using testing::kHash;
using testing::SkippingSpec;
using testing::SubmitStored;

TaskRow Row(const std::string& job, uint64_t task, TaskState state = TaskState::kQueued,
            uint32_t attempts = 0, uint32_t failures = 0, const std::string& error = "") {
  TaskRow r;
  r.job_id = job;
  r.task_id = task;
  r.state = state;
  r.attempts = attempts;
  r.failures = failures;
  r.last_error = error;
  return r;
}

void Complete(Scheduler& scheduler, const Lease& lease) {
  const CompleteResult r = scheduler.Complete(
      lease.lease_id, lease.worker_id,
      SyntheticResult(lease.task, lease.config->camera.width, lease.config->camera.height));
  ASSERT_EQ(r.status, CompleteStatus::kMerged);
}

TEST(SqliteStore, RowsSurviveReopening) {
  TempDir dir;
  const fs::path file = dir.path() / "coordinator.db";
  {
    SqliteStore db(file);
    db.PutScene({kHash, "a/scene.json", 100, 3, 36, 1, "camera-bytes", "w1\nw2", 1234});
    db.PutScene({kHash, "ignored", 0, 0, 0, 0, "", "", 0});  // content-addressed: first one stays
    db.InsertJob({"job-1", 1, std::string("spec\0bytes", 10), JobState::kQueued, "", 42, 0},
                 {Row("job-1", 0), Row("job-1", 1), Row("job-1", 2)});
    db.InsertJob({"job-2", 2, "s2", JobState::kQueued, "", 43, 0}, {Row("job-2", 0)});
    db.Apply(
        {{"job-1", 1, "", JobState::kFailed, "task 1 failed", 42, 12.5}},
        {Row("job-1", 1, TaskState::kLeased, 3, 2, "lease expired"), Row("job-1", 2, TaskState::kDone, 1)});
  }
  SqliteStore db(file);
  const auto scenes = db.LoadScenes();
  ASSERT_EQ(scenes.size(), 1u);
  EXPECT_EQ(scenes[0].entry, "a/scene.json");
  EXPECT_EQ(scenes[0].triangles, 36u);
  EXPECT_EQ(scenes[0].default_camera, "camera-bytes");
  EXPECT_EQ(scenes[0].warnings, "w1\nw2");
  const auto jobs = db.LoadJobs();
  ASSERT_EQ(jobs.size(), 2u);
  EXPECT_EQ(jobs[0].job_id, "job-1");
  EXPECT_EQ(jobs[0].spec, std::string("spec\0bytes", 10));
  EXPECT_EQ(jobs[0].state, JobState::kFailed);
  EXPECT_EQ(jobs[0].failure_reason, "task 1 failed");
  EXPECT_EQ(jobs[0].elapsed_seconds, 12.5);
  EXPECT_EQ(jobs[0].submitted_unix_ms, 42);
  EXPECT_EQ(jobs[1].job_id, "job-2");
  const auto tasks = db.LoadTasks("job-1");
  ASSERT_EQ(tasks.size(), 3u);
  EXPECT_EQ(tasks[0].state, TaskState::kQueued);
  EXPECT_EQ(tasks[1].state, TaskState::kLeased);
  EXPECT_EQ(tasks[1].attempts, 3u);
  EXPECT_EQ(tasks[1].failures, 2u);
  EXPECT_EQ(tasks[1].last_error, "lease expired");
  EXPECT_EQ(tasks[2].state, TaskState::kDone);
}

// A deleted job's rows are gone after reopening (a restart never brings it back); the other
// job keeps its rows, and deleting an unknown id changes nothing.
TEST(SqliteStore, DeletedJobsDoNotComeBackAfterReopening) {
  TempDir dir;
  const fs::path file = dir.path() / "coordinator.db";
  {
    SqliteStore db(file);
    db.InsertJob({"job-1", 1, "s1", JobState::kQueued, "", 42, 0}, {Row("job-1", 0), Row("job-1", 1)});
    db.InsertJob({"job-2", 2, "s2", JobState::kQueued, "", 43, 0}, {Row("job-2", 0)});
    db.DeleteJob("job-1");
    db.DeleteJob("job-unknown");
  }
  SqliteStore db(file);
  const auto jobs = db.LoadJobs();
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].job_id, "job-2");
  EXPECT_TRUE(db.LoadTasks("job-1").empty());
  EXPECT_EQ(db.CountTasks("job-1", TaskState::kQueued), 0u);
  EXPECT_EQ(db.LoadTasks("job-2").size(), 1u);
}

// Scenes.max_emission (the result bound's scale) is added to databases made before it
// existed; their scenes read back as -1 (unknown: jobs of them get no upper bound), new ones
// keep their value.
TEST(SqliteStore, DatabasesWithoutMaxEmissionAreMigrated) {
  TempDir dir;
  const fs::path file = dir.path() / "coordinator.db";
  {
    sqlite3* raw = nullptr;
    ASSERT_EQ(sqlite3_open(file.c_str(), &raw), SQLITE_OK);
    const char* old_schema =
        "CREATE TABLE scenes(hash TEXT PRIMARY KEY, entry TEXT NOT NULL, bytes INTEGER NOT NULL, "
        "files INTEGER NOT NULL, triangles INTEGER NOT NULL, lights INTEGER NOT NULL, default_camera BLOB "
        "NOT "
        "NULL, warnings TEXT NOT NULL, created_unix_ms INTEGER NOT NULL);"
        "INSERT INTO scenes VALUES('old', 'a.json', 1, 1, 36, 1, x'', '', 5);";
    EXPECT_EQ(sqlite3_exec(raw, old_schema, nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(raw);
  }
  {
    SqliteStore db(file);
    SceneRow fresh{"new", "b.json", 1, 1, 36, 1, "", "", 6};
    fresh.max_emission = 17;
    db.PutScene(fresh);
  }
  SqliteStore db(file);  // a second open must not add the column again
  const auto scenes = db.LoadScenes();
  ASSERT_EQ(scenes.size(), 2u);
  EXPECT_EQ(scenes[0].hash, "old");
  EXPECT_EQ(scenes[0].max_emission, -1.0);
  EXPECT_EQ(scenes[1].hash, "new");
  EXPECT_EQ(scenes[1].max_emission, 17.0);
}

TEST(Checkpoint, RoundTripAndCorruptionIsDetected) {
  Accumulator acc(3, 2);
  const std::vector<uint32_t> px = {0, 4};
  const std::vector<float> sums = {1, 2, 3, 4, 5, 6};
  acc.Add(px, sums, 2);
  Checkpoint cp{"job-9", 1, {5}, acc.Serialize(), 4, {"w1", "w2"}};
  const std::string bytes = EncodeCheckpoint(cp);
  const Checkpoint back = DecodeCheckpoint(bytes);
  EXPECT_EQ(back.job_id, "job-9");
  EXPECT_EQ(back.epoch, 4u);
  EXPECT_EQ(back.convicted, (std::vector<std::string>{"w1", "w2"}));
  EXPECT_EQ(back.merge_seq, 1u);
  EXPECT_EQ(back.merged_task_ids, std::vector<uint64_t>{5});
  EXPECT_EQ(Accumulator::Deserialize(back.accumulator), acc);

  for (size_t pos : {size_t(0), size_t(20), bytes.size() / 2, bytes.size() - 1}) {
    std::string bad = bytes;
    bad[pos] ^= 0x10;
    EXPECT_THROW(DecodeCheckpoint(bad), InputError) << pos;
  }
  EXPECT_THROW(DecodeCheckpoint(bytes.substr(0, bytes.size() - 9)), InputError);
  EXPECT_THROW(DecodeCheckpoint(""), InputError);
  // Convicted worker lists that are not a list of non-empty lines (with a valid checksum).
  for (const std::vector<std::string>& bad :
       {std::vector<std::string>{""}, std::vector<std::string>{"a\nb", ""}}) {
    Checkpoint odd = cp;
    odd.convicted = bad;
    EXPECT_THROW(DecodeCheckpoint(EncodeCheckpoint(odd)), InputError);
  }
}

TEST(Checkpoint, FilesAreWrittenAtomically) {
  TempDir dir;
  const fs::path file = dir.path() / "job-1.acc";
  EXPECT_FALSE(ReadCheckpointFile(file).has_value());
  Accumulator acc(2, 2);
  WriteCheckpointFile(file, {"job-1", 0, {}, acc.Serialize(), 0, {}});
  WriteCheckpointFile(file, {"job-1", 3, {0, 1, 7}, acc.Serialize(), 0, {}});
  const std::optional<Checkpoint> cp = ReadCheckpointFile(file);
  ASSERT_TRUE(cp.has_value());
  EXPECT_EQ(cp->merge_seq, 3u);
  EXPECT_EQ(cp->merged_task_ids, (std::vector<uint64_t>{0, 1, 7}));
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_FALSE(IsTemporaryName(e.path().filename().string())) << "left behind: " << e.path();
  std::ofstream(file, std::ios::binary | std::ios::trunc) << "garbage";
  EXPECT_THAT([&] { (void)ReadCheckpointFile(file); },
              ::testing::ThrowsMessage<InputError>(HasSubstr("job-1.acc")))
      << "read a corrupt checkpoint";
}

TEST(Journal, EntriesRoundTripAndATornTailIsCut) {
  TempDir dir;
  const fs::path file = dir.path() / "job-1.journal";
  uint64_t valid = 1;
  EXPECT_TRUE(ReadJournalFile(file, &valid).empty());
  EXPECT_EQ(valid, 0u);
  const std::string a = EncodeJournalEntry(3, 5, std::vector<float>{1.5f, -2, 3});
  const std::string b = EncodeJournalEntry(9, 0, std::vector<float>{});
  const std::string c = EncodeJournalEntry(4, 0, std::vector<float>{7, 8, 9, 10, 11, 12});
  // An entry written before epochs ("PFJ1", no epoch field) reads as epoch 0.
  std::string v1;
  ByteWriter w(v1);
  w.PutBytes("PFJ1");
  w.Put<uint64_t>(8);
  w.Put<uint32_t>(1);
  w.Put<float>(2.5f);
  w.Put<uint64_t>(Checksum64(v1));
  std::ofstream(file, std::ios::binary) << a << b << v1 << c.substr(0, c.size() - 3);  // torn append
  const std::vector<JournalEntry> entries = ReadJournalFile(file, &valid);
  ASSERT_EQ(entries.size(), 3u);
  EXPECT_EQ(entries[0].task_id, 3u);
  EXPECT_EQ(entries[0].epoch, 5u);
  EXPECT_EQ(entries[0].rgb_sums, (std::vector<float>{1.5f, -2, 3}));
  EXPECT_EQ(entries[1].task_id, 9u);
  EXPECT_EQ(entries[2].task_id, 8u);
  EXPECT_EQ(entries[2].epoch, 0u);
  EXPECT_EQ(entries[2].rgb_sums, std::vector<float>{2.5f});
  EXPECT_EQ(valid, a.size() + b.size() + v1.size());
  std::string flipped = a;
  flipped[14] ^= 1;
  std::ofstream(file, std::ios::binary | std::ios::trunc) << flipped << b;
  EXPECT_TRUE(ReadJournalFile(file, &valid).empty()) << "a corrupt entry ends the journal";
}

// A byte flipped mid-journal lost acknowledged results and was logged only as a "torn
// entry" warning. Damage before the end is now told apart from a torn tail.
TEST(Journal, DamageBeforeTheEndIsNotATornTail) {
  TempDir dir;
  const fs::path file = dir.path() / "j.journal";
  const std::string a = EncodeJournalEntry(3, 0, std::vector<float>{1, 2, 3});
  const std::string b = EncodeJournalEntry(4, 0, std::vector<float>{4, 5, 6});
  const std::string c = EncodeJournalEntry(5, 0, std::vector<float>{7, 8, 9});
  uint64_t valid = 0;
  bool damaged = true;
  std::ofstream(file, std::ios::binary | std::ios::trunc) << a << b << c.substr(0, c.size() - 1);
  EXPECT_EQ(ReadJournalFile(file, &valid, &damaged).size(), 2u);
  EXPECT_FALSE(damaged) << "torn tail";
  for (size_t at : {size_t(1), size_t(18), b.size() - 2}) {  // magic, a value, the checksum of b
    std::string bad = b;
    bad[at] ^= 0x40;
    std::ofstream(file, std::ios::binary | std::ios::trunc) << a << bad << c;
    EXPECT_EQ(ReadJournalFile(file, &valid, &damaged).size(), 1u) << at;
    EXPECT_EQ(valid, a.size());
    EXPECT_TRUE(damaged) << "byte " << at << " of the middle entry";
  }
  // The last entry damaged in place (nothing follows): indistinguishable from a torn append.
  std::string last = c;
  last[20] ^= 1;
  std::ofstream(file, std::ios::binary | std::ios::trunc) << a << b << last;
  EXPECT_EQ(ReadJournalFile(file, &valid, &damaged).size(), 2u);
  EXPECT_FALSE(damaged);
}

// An entry that could not be written whole is cut off, so a later, shorter entry is not followed
// by the torn one's bytes (which would read as damage and hide what follows).
TEST(JournalWriter, ATornAppendLeavesNothingBehindAShorterEntry) {
  TempDir dir;
  const fs::path file = dir.path() / "j.journal";
  testing::FaultInjector faults;
  testing::FaultyFiles files(faults);
  JournalWriter journal(file, files);
  const std::vector<float> big(300, 1.5f), small(3, 2.5f);
  std::string problem;
  ASSERT_TRUE(journal.Append(EncodeJournalEntry(1, 0, big), &problem)) << problem;
  faults.Arm({testing::FileOp::kWrite, ".journal", false, 1, 1, ENOSPC, /*torn=*/true});
  EXPECT_FALSE(journal.Append(EncodeJournalEntry(2, 0, big), &problem));
  EXPECT_THAT(problem, HasSubstr("No space left on device"));
  EXPECT_FALSE(journal.broken()) << "the torn entry was cut off";
  ASSERT_TRUE(journal.Append(EncodeJournalEntry(3, 0, small), &problem)) << problem;
  ASSERT_TRUE(journal.Sync(&problem)) << problem;
  uint64_t valid = 0;
  bool damaged = false;
  const std::vector<JournalEntry> entries = ReadJournalFile(file, &valid, &damaged);
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_EQ(entries[0].task_id, 1u);
  EXPECT_EQ(entries[1].task_id, 3u);
  EXPECT_FALSE(damaged);
  EXPECT_EQ(valid, fs::file_size(file));
  // If the cut fails too, the journal takes nothing until a reset removes it.
  faults.Arm({testing::FileOp::kWrite, ".journal", false, 1, 1, EIO, /*torn=*/true});
  faults.Arm({testing::FileOp::kFtruncate, ".journal", false, 1, 1, EIO});
  EXPECT_FALSE(journal.Append(EncodeJournalEntry(4, 0, small), &problem));
  EXPECT_THAT(problem, HasSubstr("cannot be cut off"));
  EXPECT_TRUE(journal.broken());
  faults.Disarm();
  EXPECT_FALSE(journal.Append(EncodeJournalEntry(5, 0, small), &problem)) << "not behind a torn entry";
  ASSERT_TRUE(journal.Reset(&problem)) << problem;
  EXPECT_FALSE(fs::exists(file));
  ASSERT_TRUE(journal.Append(EncodeJournalEntry(6, 0, small), &problem)) << problem;
  EXPECT_EQ(ReadJournalFile(file, &valid, &damaged).size(), 1u);
}

TEST(Persister, DurableAcknowledgementsWaitForTheJournal) {
  TempDir dir;
  FakeClock clock;
  FakeCatalog catalog;
  SqliteStore db(dir.path() / "db");
  Scheduler scheduler(clock, {});
  Persister persister(scheduler, db, dir.path() / "checkpoints", clock, /*interval=*/0);
  const std::string id = SubmitStored(scheduler, db, ValidateJobSpec(SkippingSpec(2, 1), catalog));
  const Lease lease = *scheduler.TryLease({"w", {}});
  const std::vector<float> sums = SyntheticResult(lease.task, 12, 10);
  ASSERT_EQ(scheduler.Complete(lease.lease_id, lease.worker_id, sums).status, CompleteStatus::kMerged);
  bool acked = false;
  persister.JournalThenAck(id, lease.task_id, 0, 1, sums,
                           [&](const std::string& not_stored) { acked = not_stored.empty(); });
  EXPECT_FALSE(acked) << "nothing on disk yet";
  persister.FlushNow(/*checkpoints_due=*/false);
  EXPECT_TRUE(acked);
  EXPECT_FALSE(ReadCheckpointFile(persister.CheckpointFile(id)).has_value()) << "journal only";
  uint64_t valid = 0;
  const auto entries = ReadJournalFile(Persister::JournalFile(dir.path() / "checkpoints", id), &valid);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_EQ(entries[0].task_id, lease.task_id);
  EXPECT_EQ(entries[0].rgb_sums, sums);
  // A checkpoint takes the journal's place.
  persister.FlushNow(/*checkpoints_due=*/true);
  const std::optional<Checkpoint> cp = ReadCheckpointFile(persister.CheckpointFile(id));
  ASSERT_TRUE(cp.has_value());
  EXPECT_EQ(cp->merged_task_ids, std::vector<uint64_t>{lease.task_id});
  EXPECT_TRUE(ReadJournalFile(Persister::JournalFile(dir.path() / "checkpoints", id), &valid).empty());
  // A result merged before its job started again from nothing is never stored.
  std::string stale;
  persister.JournalThenAck(id, lease.task_id, /*epoch=*/7, 1, sums,
                           [&](const std::string& not_stored) { stale = not_stored; });
  persister.FlushNow(false);
  EXPECT_THAT(stale, HasSubstr("started again"));
  EXPECT_TRUE(ReadJournalFile(Persister::JournalFile(dir.path() / "checkpoints", id), &valid).empty());
  persister.Abandon();
  std::string late = "not called";
  persister.JournalThenAck(id, 1, 0, 1, sums, [&](const std::string& not_stored) { late = not_stored; });
  EXPECT_THAT(late, HasSubstr("stopping")) << "after a stop: answered at once, as not stored";
}

// A coordinator's data folder (database and checkpoints) that outlives its crashes in a test.
class Recovery : public ::testing::Test {
 protected:
  TempDir dir;
  FakeClock clock;
  FakeCatalog catalog;
  const fs::path db_file = dir.path() / "coordinator.db";
  const fs::path cp_dir = dir.path() / "checkpoints";
};

TEST_F(Recovery, CrashThenRestartResumesTheCheckpointedSetAndEndsBitIdentical) {
  const JobConfig config = ValidateJobSpec(SkippingSpec(2, 3), catalog);  // 12 tasks of 30 pixels

  // The reference: the same job without a crash.
  Scheduler reference(clock, {});
  std::unique_ptr<Job> ref_job = reference.PrepareJob(config);
  const std::string ref_id = ref_job->id();
  reference.AddJob(std::move(ref_job));
  while (std::optional<Lease> l = reference.TryLease({"w", {}})) Complete(reference, *l);
  ASSERT_EQ(reference.Status(ref_id).state(), v1::JOB_STATE_SUCCEEDED);

  std::string id;
  std::vector<uint64_t> checkpointed;
  uint64_t leased_at_crash = 0;
  {
    auto db = std::make_unique<SqliteStore>(db_file);
    auto scheduler = std::make_unique<Scheduler>(clock, SchedulerOptions{});
    auto persister = std::make_unique<Persister>(*scheduler, *db, cp_dir, clock, /*interval=*/0);
    id = SubmitStored(*scheduler, *db, config);
    for (int i = 0; i < 5; ++i) {
      const Lease l = *scheduler->TryLease({"w1", {}});
      checkpointed.push_back(l.task_id);
      Complete(*scheduler, l);
    }
    const Lease in_flight = *scheduler->TryLease({"w2", {}});  // leased when the coordinator dies
    leased_at_crash = in_flight.task_id;
    persister->FlushNow();
    // Acknowledged after the checkpoint: survives through the journal.
    const Lease journaled = *scheduler->TryLease({"w1", {}});
    const std::vector<float> sums = SyntheticResult(journaled.task, 12, 10);
    const CompleteResult merged = scheduler->Complete(journaled.lease_id, journaled.worker_id, sums);
    ASSERT_EQ(merged.status, CompleteStatus::kMerged);
    persister->JournalThenAck(id, journaled.task_id, 0, merged.merge_seq, sums, [](const std::string&) {});
    persister->FlushNow(/*checkpoints_due=*/false);
    checkpointed.push_back(journaled.task_id);
    // Merged in memory but never journaled (so never acknowledged): lost by the crash, must be
    // re-run, not doubled.
    Complete(*scheduler, *scheduler->TryLease({"w1", {}}));
    // Crash: no final flush, objects just go away.
    persister->Abandon();
  }
  const std::optional<Checkpoint> on_disk = ReadCheckpointFile(Persister::CheckpointFile(cp_dir, id));
  ASSERT_TRUE(on_disk.has_value());
  std::sort(checkpointed.begin(), checkpointed.end());
  EXPECT_EQ(on_disk->merged_task_ids.size(), 5u);

  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  const RecoveryReport report = RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_EQ(report.jobs_resumed, 1u);
  EXPECT_EQ(report.tasks_merged, 6u);
  EXPECT_EQ(report.tasks_from_journal, 1u);
  EXPECT_EQ(report.tasks_requeued, 6u);
  v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_RUNNING);
  EXPECT_EQ(s.tasks_done(), 6u);
  EXPECT_EQ(s.spec().name(), "crash test");
  // Re-run exactly the tasks that are not in the checkpoint; the one leased at the crash gets its
  // next attempt number (its first lease was persisted) without a failure being counted.
  std::vector<uint64_t> rerun;
  while (std::optional<Lease> l = scheduler.TryLease({"w3", {}})) {
    if (l->task_id == leased_at_crash) {
      EXPECT_EQ(l->attempt, 2u);
    }
    rerun.push_back(l->task_id);
    Complete(scheduler, *l);
  }
  std::sort(rerun.begin(), rerun.end());
  std::vector<uint64_t> expected;
  for (uint64_t t = 0; t < 12; ++t)
    if (!std::binary_search(checkpointed.begin(), checkpointed.end(), t)) expected.push_back(t);
  EXPECT_EQ(rerun, expected);
  s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_done(), 12u);
  const JobSnapshot after = scheduler.Snapshot(id, true), ref = reference.Snapshot(ref_id, true);
  ASSERT_TRUE(after.image && ref.image);
  EXPECT_EQ(after.image->samples_merged, ref.image->samples_merged);
  for (size_t p = 0; p < ref.image->image.size(); ++p)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(after.image->image[p][c], ref.image->image[p][c]) << p;
  EXPECT_EQ(scheduler.counters().failed_attempts, 0u);
  // A further id never collides with the recovered one.
  EXPECT_NE(scheduler.PrepareJob(config)->id(), id);
}

TEST_F(Recovery, FinishedJobsAreListedAndCorruptCheckpointsRestartTheJob) {
  std::string done_id, broken_id;
  {
    SqliteStore db(db_file);
    Scheduler scheduler(clock, SchedulerOptions{});
    Persister persister(scheduler, db, cp_dir, clock, 0);
    done_id = SubmitStored(scheduler, db, ValidateJobSpec(SkippingSpec(1, 2), catalog));
    while (std::optional<Lease> l = scheduler.TryLease({"w", {}})) Complete(scheduler, *l);
    broken_id = SubmitStored(scheduler, db, ValidateJobSpec(SkippingSpec(1, 3), catalog));
    Complete(scheduler, *scheduler.TryLease({"w", {}}));
    persister.Stop();  // graceful: everything flushed
  }
  std::ofstream(Persister::CheckpointFile(cp_dir, broken_id), std::ios::binary | std::ios::trunc) << "torn";
  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  const RecoveryReport report = RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_EQ(report.jobs_finished, 1u);
  EXPECT_EQ(report.jobs_resumed, 1u);
  const v1::JobStatus done = scheduler.Status(done_id);
  EXPECT_EQ(done.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(done.tasks_done(), 2u);
  EXPECT_EQ(done.samples_merged(), 2u * 2 * 120) << "2 rounds x 2 spp x 120 pixels, from the jobs table";
  EXPECT_GE(done.estimated_noise_rms(), 0.0);
  const JobSnapshot snap = scheduler.Snapshot(done_id, true);
  EXPECT_FALSE(snap.image.has_value()) << "finished jobs are not held in memory";
  EXPECT_EQ(snap.checkpoint_path, Persister::CheckpointFile(cp_dir, done_id).string());
  EXPECT_EQ(scheduler.Status(broken_id).tasks_done(), 0u) << "corrupt checkpoint: from zero";
  EXPECT_EQ(scheduler.List(false).size(), 1u);
  EXPECT_EQ(scheduler.List(true).size(), 2u);

  // The finished job's image lives only in its checkpoint. Damaged, it was
  // INVALID_ARGUMENT with a server path (and `pf get` said "invalid input"); now DATA_LOSS
  // naming the job only. Missing, it was a black image; now DATA_LOSS too.
  EXPECT_EQ(EncodeJobImage(scheduler, done_id).chunks.size(), 1u);
  const fs::path done_cp = Persister::CheckpointFile(cp_dir, done_id);
  std::string bytes;
  {
    std::ifstream in(done_cp, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  bytes[bytes.size() / 2] ^= 1;
  std::ofstream(done_cp, std::ios::binary | std::ios::trunc) << bytes;
  for (int missing = 0; missing < 2; ++missing) {
    if (missing) fs::remove(done_cp);
    const grpc::Status st = StatusFromException(
        [&] {
          try {
            EncodeJobImage(scheduler, done_id);
          } catch (...) {
            return std::current_exception();
          }
          return std::exception_ptr();
        }(),
        "GetImage");
    EXPECT_EQ(st.error_code(), grpc::StatusCode::DATA_LOSS) << st.error_message();
    EXPECT_NE(st.error_message().find(done_id), std::string::npos) << st.error_message();
    EXPECT_EQ(st.error_message().find(dir.path().string()), std::string::npos) << st.error_message();
  }
}

// The job table is lost (SQLite file deleted with its WAL) while a job's journal and
// checkpoint survive. Before, the id counter restarted, the next job got the old id and the old
// journal was replayed into it (a wrong image that SUCCEEDED). Ids are random now: the new job
// gets another id, starts from zero merges, and the old files are set aside and reported.
TEST_F(Recovery, ALostJobTableNeverReusesAnIdAndOldFilesAreSetAside) {
  std::string old_id;
  {
    SqliteStore db(db_file);
    Scheduler scheduler(clock, SchedulerOptions{});
    Persister persister(scheduler, db, cp_dir, clock, 0);
    old_id = SubmitStored(scheduler, db, ValidateJobSpec(SkippingSpec(1, 3), catalog));
    Complete(scheduler, *scheduler.TryLease({"w", {}}));
    persister.Stop();  // the unfinished job's checkpoint stays
  }
  ASSERT_TRUE(fs::exists(Persister::JournalFile(cp_dir, old_id)) ||
              fs::exists(Persister::CheckpointFile(cp_dir, old_id)));
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(db_file.string() + suffix);

  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_FALSE(fs::exists(Persister::JournalFile(cp_dir, old_id)));
  EXPECT_FALSE(fs::exists(Persister::CheckpointFile(cp_dir, old_id)));
  EXPECT_TRUE(fs::exists(Persister::JournalFile(cp_dir, old_id).string() + ".orphaned") ||
              fs::exists(Persister::CheckpointFile(cp_dir, old_id).string() + ".orphaned"));
  Persister persister(scheduler, db, cp_dir, clock, 0);
  const std::string new_id = SubmitStored(scheduler, db, ValidateJobSpec(SkippingSpec(1, 3), catalog));
  EXPECT_NE(new_id, old_id);
  EXPECT_EQ(scheduler.Status(new_id).tasks_done(), 0u) << "nothing of the old job merged into the new one";
  persister.Stop();
}

// The progressive schedule's α was 2/3 by default and is 1/2 now. A progressive photon-map job is
// stored with its α written out; one stored before that, with α unset, resumes with 2/3, the α it
// started with, not today's default.
TEST_F(Recovery, AProgressiveJobResumesWithTheAlphaItWasStoredWith) {
  v1::JobSpec spec = SkippingSpec(1, 1);
  spec.mutable_settings()->set_integrator(v1::INTEGRATOR_PHOTONMAP);
  spec.mutable_settings()->mutable_photon_map()->set_photons(1000);
  spec.mutable_settings()->mutable_photon_map()->set_k(10);
  spec.mutable_plan()->mutable_progressive()->set_passes(2);
  spec.mutable_plan()->mutable_progressive()->set_samples_per_pixel(1);
  std::string fresh_id, old_id;
  {
    SqliteStore db(db_file);
    Scheduler scheduler(clock, SchedulerOptions{});
    const JobConfig fresh = ValidateJobSpec(spec, catalog);
    ASSERT_TRUE(fresh.spec.settings().photon_map().has_progressive_alpha()) << "written out, default or not";
    EXPECT_EQ(fresh.spec.settings().photon_map().progressive_alpha(), kDefaultProgressiveAlpha);
    fresh_id = SubmitStored(scheduler, db, fresh);
    JobConfig old = ValidateJobSpec(spec, catalog);
    old.spec.mutable_settings()->mutable_photon_map()->clear_progressive_alpha();  // as stored before
    old_id = SubmitStored(scheduler, db, old);
  }
  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  EXPECT_EQ(RecoverJobs(db, catalog, cp_dir, scheduler, clock).jobs_resumed, 2u);
  EXPECT_EQ(scheduler.Status(fresh_id).spec().settings().photon_map().progressive_alpha(), 0.5);
  EXPECT_EQ(scheduler.Status(old_id).spec().settings().photon_map().progressive_alpha(), 2.0 / 3.0);
  EXPECT_EQ(scheduler.Snapshot(old_id, false).config->settings.progressive_alpha, 2.0 / 3.0);
}

// Elapsed time was saved only on state changes, so a time budget restarted with the
// coordinator. Now a running job's elapsed time is persisted every kElapsedPersistSeconds and
// the budget counts across a restart (the downtime does not).
TEST_F(Recovery, ElapsedTimeAndItsBudgetSurviveARestart) {
  v1::JobSpec spec = SkippingSpec(1, 3);
  spec.mutable_stop()->set_time_budget_seconds(10);
  std::string id;
  {
    SqliteStore db(db_file);
    Scheduler scheduler(clock, SchedulerOptions{.lease_seconds = 100});
    Persister persister(scheduler, db, cp_dir, clock, 0);
    id = SubmitStored(scheduler, db, ValidateJobSpec(spec, catalog));
    ASSERT_TRUE(scheduler.TryLease({"w", {}}).has_value());  // running from now
    persister.FlushNow();                                    // the row says: running, 0 s
    clock.Advance(6);
    scheduler.Tick();
    persister.FlushNow();  // before the fix: nothing dirty, the row kept 0 s
    persister.Abandon();   // a crash
  }
  clock.Advance(100);  // downtime
  SqliteStore db(db_file);
  for (const JobRow& row : db.LoadJobs()) {
    if (row.job_id == id) {
      EXPECT_NEAR(row.elapsed_seconds, 6.0, 1e-6);
    }
  }
  Scheduler scheduler(clock, SchedulerOptions{});
  RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_NEAR(scheduler.Status(id).elapsed_seconds(), 6.0, 1e-6) << "the downtime does not count";
  clock.Advance(3);
  scheduler.Tick();
  EXPECT_TRUE(scheduler.Status(id).state() == v1::JOB_STATE_RUNNING) << "9 s of 10";
  clock.Advance(2);
  scheduler.Tick();
  EXPECT_NE(scheduler.Status(id).state(), v1::JOB_STATE_RUNNING) << "11 s: the budget is spent";
}

v1::JobSpec HierarchicalSpec() {
  v1::JobSpec spec = SkippingSpec(2, 1);
  v1::Hierarchical* h = spec.mutable_plan()->mutable_hierarchical();
  h->set_levels(2);
  h->set_dims(2);
  h->set_base_samples(2);
  h->set_min_samples(1);
  h->set_decay(2);
  h->set_localize_threshold(0.5);  // low thresholds: the synthetic noise localizes many pixels
  h->set_localize_contrast(0);
  h->set_samples_per_pixel(1);
  h->set_rows_per_task(4);  // 3 row bands: up to n0 × 3 localization tasks
  return spec;
}

TEST_F(Recovery, HierarchicalJobRederivesItsLocalizationTasks) {
  const JobConfig config = ValidateJobSpec(HierarchicalSpec(), catalog);
  const uint64_t static_tasks = ScheduledTasks(config).size();

  Scheduler reference(clock, {});
  std::unique_ptr<Job> ref_job = reference.PrepareJob(config);
  const std::string ref_id = ref_job->id();
  reference.AddJob(std::move(ref_job));
  while (std::optional<Lease> l = reference.TryLease({"w", {}})) Complete(reference, *l);
  const v1::JobStatus ref_status = reference.Status(ref_id);
  ASSERT_EQ(ref_status.state(), v1::JOB_STATE_SUCCEEDED);
  ASSERT_GT(ref_status.tasks_total(), static_tasks + 2) << "localization tasks were created";

  std::string id;
  uint64_t merged_before_crash = 0;
  {
    auto db = std::make_unique<SqliteStore>(db_file);
    auto scheduler = std::make_unique<Scheduler>(clock, SchedulerOptions{});
    auto persister = std::make_unique<Persister>(*scheduler, *db, cp_dir, clock, /*interval=*/0);
    id = SubmitStored(*scheduler, *db, config);
    // Everything static, and one created task: checkpointed.
    for (uint64_t i = 0; i <= static_tasks; ++i) Complete(*scheduler, *scheduler->TryLease({"w1", {}}));
    ASSERT_GT(scheduler->Status(id).tasks_total(), static_tasks + 1);
    persister->FlushNow();
    // One more created task, acknowledged through the journal.
    const Lease journaled = *scheduler->TryLease({"w1", {}});
    ASSERT_GE(journaled.task_id, static_tasks);
    const std::vector<float> sums = SyntheticResult(journaled.task, 12, 10);
    const CompleteResult merged = scheduler->Complete(journaled.lease_id, journaled.worker_id, sums);
    ASSERT_EQ(merged.status, CompleteStatus::kMerged);
    persister->JournalThenAck(id, journaled.task_id, 0, merged.merge_seq, sums, [](const std::string&) {});
    persister->FlushNow(/*checkpoints_due=*/false);
    merged_before_crash = static_tasks + 2;
    persister->Abandon();
  }

  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  const RecoveryReport report = RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_EQ(report.jobs_resumed, 1u);
  EXPECT_EQ(report.tasks_merged, merged_before_crash);
  EXPECT_EQ(report.tasks_from_journal, 1u);
  while (std::optional<Lease> l = scheduler.TryLease({"w3", {}})) {
    EXPECT_GE(l->task_id, merged_before_crash) << "merged before the crash, re-run";
    Complete(scheduler, *l);
  }
  const v1::JobStatus s = scheduler.Status(id);
  EXPECT_EQ(s.state(), v1::JOB_STATE_SUCCEEDED);
  EXPECT_EQ(s.tasks_total(), ref_status.tasks_total());
  EXPECT_EQ(s.samples_merged(), ref_status.samples_merged());
  const JobSnapshot after = scheduler.Snapshot(id, true), ref = reference.Snapshot(ref_id, true);
  ASSERT_TRUE(after.image && ref.image);
  for (size_t p = 0; p < ref.image->image.size(); ++p)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(after.image->image[p][c], ref.image->image[p][c]) << p;
}

// A checkpoint names merged tasks by id. A job stored under another version of its plan's
// expansion (task_plan.h PlanExpansionVersion) must not resume them: its results are set aside,
// its tasks re-run, and it ends with the image of an uninterrupted run.
TEST_F(Recovery, AJobOfAnotherPlanExpansionVersionIsReRunFromZero) {
  const JobConfig config = ValidateJobSpec(HierarchicalSpec(), catalog);
  ASSERT_EQ(PlanExpansionVersion(config.plan), 3u);
  Scheduler reference(clock, {});
  std::unique_ptr<Job> ref_job = reference.PrepareJob(config);
  EXPECT_EQ(ref_job->config().spec.plan().expansion_version(), 3u) << "stamped at submit";
  const std::string ref_id = ref_job->id();
  reference.AddJob(std::move(ref_job));
  while (std::optional<Lease> l = reference.TryLease({"w", {}})) Complete(reference, *l);
  const JobSnapshot ref = reference.Snapshot(ref_id, true);
  ASSERT_TRUE(ref.image);

  std::string id;
  {
    auto db = std::make_unique<SqliteStore>(db_file);
    auto scheduler = std::make_unique<Scheduler>(clock, SchedulerOptions{});
    auto persister = std::make_unique<Persister>(*scheduler, *db, cp_dir, clock, /*interval=*/0);
    id = SubmitStored(*scheduler, *db, config);
    for (int i = 0; i < 3; ++i) Complete(*scheduler, *scheduler->TryLease({"w1", {}}));
    persister->FlushNow();
    persister->Abandon();
  }
  ASSERT_TRUE(fs::exists(Persister::CheckpointFile(cp_dir, id)));
  // As if an older coordinator (expansion version 2: detail tasks with independent pixel streams)
  // had stored the job.
  {
    SqliteStore db(db_file);
    v1::JobSpec old_spec = config.spec;
    old_spec.mutable_plan()->set_expansion_version(2);
    db.UpdateJobSpec(id, old_spec.SerializeAsString());
  }

  SqliteStore db(db_file);
  Scheduler scheduler(clock, SchedulerOptions{});
  const RecoveryReport report = RecoverJobs(db, catalog, cp_dir, scheduler, clock);
  EXPECT_EQ(report.jobs_reexpanded, 1u);
  EXPECT_EQ(report.jobs_resumed, 1u);
  EXPECT_EQ(report.tasks_merged, 0u) << "the old checkpoint's task ids are not trusted";
  EXPECT_FALSE(fs::exists(Persister::CheckpointFile(cp_dir, id)));
  fs::path aside = Persister::CheckpointFile(cp_dir, id);
  aside += ".expansion-v2";
  EXPECT_TRUE(fs::exists(aside)) << "set aside, not deleted";
  v1::JobSpec stored;
  ASSERT_TRUE(stored.ParseFromString(db.LoadJobs().at(0).spec));
  EXPECT_EQ(stored.plan().expansion_version(), 3u) << "a second restart resumes normally";
  while (std::optional<Lease> l = scheduler.TryLease({"w3", {}})) Complete(scheduler, *l);
  EXPECT_EQ(scheduler.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
  const JobSnapshot after = scheduler.Snapshot(id, true);
  ASSERT_TRUE(after.image);
  for (size_t p = 0; p < ref.image->image.size(); ++p)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(after.image->image[p][c], ref.image->image[p][c]) << p;
}

// A job submitted under another coordinator build (so rendered by that build's workers) must not
// mix its merged results with this build's (docs/farm.md, Upgrades): they are set aside, its tasks
// re-run with fresh attempts, and it ends with the image of an uninterrupted run; a job stored
// before the field (no build) counts as another build. A coordinator that keeps other builds
// (--allow-mixed-versions) resumes it instead, and re-stamps it so that its next restart resumes.
TEST_F(Recovery, AJobSubmittedUnderAnotherBuildIsReRunFromZeroUnlessMixedBuildsAreAllowed) {
  const JobConfig config = ValidateJobSpec(SkippingSpec(2, 3), catalog);  // 12 tasks
  SchedulerOptions old_build, new_build;
  old_build.build = "0.1.0-old";
  new_build.build = "0.1.0-new";
  Scheduler reference(clock, new_build);
  std::unique_ptr<Job> ref_job = reference.PrepareJob(config);
  const std::string ref_id = ref_job->id();
  reference.AddJob(std::move(ref_job));
  while (std::optional<Lease> l = reference.TryLease({"w", {}})) Complete(reference, *l);
  const JobSnapshot ref = reference.Snapshot(ref_id, true);
  ASSERT_TRUE(ref.image);
  const auto stored_spec = [](SqliteStore& db) {
    v1::JobSpec spec;
    EXPECT_TRUE(spec.ParseFromString(db.LoadJobs().at(0).spec));
    return spec;
  };
  // Submitted under `build` (nullopt: stored before the field), 3 tasks merged and checkpointed.
  const auto crash_after_three = [&](const fs::path& root, const std::optional<std::string>& build) {
    auto db = std::make_unique<SqliteStore>(root / "coordinator.db");
    SchedulerOptions o;
    o.build = build.value_or("");
    auto scheduler = std::make_unique<Scheduler>(clock, o);
    auto persister =
        std::make_unique<Persister>(*scheduler, *db, root / "checkpoints", clock, /*interval=*/0);
    const std::string id = SubmitStored(*scheduler, *db, config);
    EXPECT_EQ(stored_spec(*db).plan().build(), o.build) << "stamped at submit";
    for (int i = 0; i < 3; ++i) Complete(*scheduler, *scheduler->TryLease({"w1", {}}));
    persister->FlushNow();
    persister->Abandon();
    return id;
  };

  for (const std::optional<std::string>& stored :
       {std::optional<std::string>("0.1.0-old"), std::optional<std::string>()}) {
    SCOPED_TRACE(stored.value_or("(stored before the field)"));
    TempDir root;
    const std::string id = crash_after_three(root.path(), stored);
    SqliteStore db(root.path() / "coordinator.db");
    Scheduler scheduler(clock, new_build);
    const RecoveryReport report = RecoverJobs(db, catalog, root.path() / "checkpoints", scheduler, clock);
    EXPECT_EQ(report.jobs_resumed, 1u);
    EXPECT_EQ(report.jobs_other_build, 1u);
    EXPECT_EQ(report.jobs_reexpanded, 0u);
    EXPECT_EQ(report.tasks_merged, 0u) << "another build's results are not merged into this build's";
    fs::path aside = Persister::CheckpointFile(root.path() / "checkpoints", id);
    aside += ".other-build";
    EXPECT_TRUE(fs::exists(aside)) << "set aside, not deleted";
    EXPECT_EQ(stored_spec(db).plan().build(), "0.1.0-new") << "a second restart resumes normally";
    uint64_t rerun = 0;
    while (std::optional<Lease> l = scheduler.TryLease({"w2", {}})) {
      EXPECT_EQ(l->attempt, 1u) << "task " << l->task_id << ": attempts start afresh";
      Complete(scheduler, *l);
      ++rerun;
    }
    EXPECT_EQ(rerun, 12u);
    EXPECT_EQ(scheduler.Status(id).state(), v1::JOB_STATE_SUCCEEDED);
    const JobSnapshot after = scheduler.Snapshot(id, true);
    ASSERT_TRUE(after.image);
    for (size_t p = 0; p < ref.image->image.size(); ++p)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(after.image->image[p][c], ref.image->image[p][c]) << p;
  }

  // The same crash, recovered by a coordinator that keeps other builds: resumed as it was, and
  // stamped with the new build.
  TempDir mixed;
  const std::string mixed_id = crash_after_three(mixed.path(), "0.1.0-old");
  SqliteStore mixed_db(mixed.path() / "coordinator.db");
  Scheduler keeping(clock, new_build);
  const RecoveryReport kept = RecoverJobs(mixed_db, catalog, mixed.path() / "checkpoints", keeping, clock,
                                          /*keep_other_builds=*/true);
  EXPECT_EQ(kept.jobs_other_build, 0u);
  EXPECT_EQ(kept.tasks_merged, 3u);
  EXPECT_EQ(keeping.Status(mixed_id).tasks_done(), 3u);
  EXPECT_EQ(stored_spec(mixed_db).plan().build(), "0.1.0-new");
}

}  // namespace
}  // namespace pf::server
