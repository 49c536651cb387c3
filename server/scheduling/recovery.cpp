#include "server/scheduling/recovery.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <set>

#include "common/core/error.h"
#include "common/plan/hierarchical.h"
#include "common/render/progressive_radius.h"
#include "proto/limits.h"
#include "server/assembly/result_merger.h"
#include "server/scheduling/checkpoint_restore.h"
#include "server/store/checkpoint.h"
#include "server/store/journal.h"
#include "server/store/persister.h"

namespace pf::server {
namespace fs = std::filesystem;

namespace {

uint64_t ReplayEntries(const std::vector<JournalEntry>& entries, Job& job, ResultMerger& merger);

// Merges the journal's entries for tasks not merged yet; cuts a torn tail. Returns how many.
uint64_t ReplayJournal(const fs::path& file, Job& job, RecoveryReport& report) {
  uint64_t valid = 0;
  bool damaged = false;
  std::vector<JournalEntry> entries;
  try {
    entries = ReadJournalFile(file, &valid, &damaged);
  } catch (const std::exception& e) {
    spdlog::error("job {}: journal unreadable ({}); its results are re-run", job.id(), e.what());
    return 0;
  }
  std::error_code ec;
  if (damaged) {
    // Acknowledged results are unreadable: an error for the operator, with the file kept. The
    // image stays right (the tasks are re-run; rendering is deterministic).
    ++report.journals_damaged;
    fs::path kept = file;
    kept += ".damaged";
    fs::copy_file(file, kept, fs::copy_options::overwrite_existing, ec);
    spdlog::error(
        "job {}: DATA LOSS: journal damaged after byte {} of {} (acknowledged results unreadable); "
        "{} entries kept, the other tasks are re-run; damaged file {}",
        job.id(), valid, fs::file_size(file, ec), entries.size(),
        ec ? "could not be copied (" + ec.message() + ")" : "kept as " + kept.filename().string());
    if (!ec) fs::resize_file(file, valid, ec);
  } else if (fs::exists(file, ec) && fs::file_size(file, ec) > valid) {
    spdlog::warn("job {}: journal ends in a torn entry (an unacknowledged result); cut at {} bytes", job.id(),
                 valid);
    fs::resize_file(file, valid, ec);
  }
  ResultMerger merger;
  uint64_t merged = 0;
  // A dynamic plan creates tasks from merged results: entries for them apply once the entries
  // they follow from have been merged, so replay until nothing changes.
  for (bool again = true; again;) {
    const uint64_t before = merged;
    merged += ReplayEntries(entries, job, merger);
    // Without a loaded accumulator nothing was merged, so nothing can follow from results; asking
    // job.accumulator() would allocate the image of every resumed job (the accumulator is lazy).
    const Accumulator* acc = job.accumulator_if_loaded();
    const std::vector<TaskSpec> created = acc ? TasksCreatedFromResults(job, *acc) : std::vector<TaskSpec>{};
    job.AppendTasks(created);
    again = merged > before && !created.empty();
  }
  return merged;
}

uint64_t ReplayEntries(const std::vector<JournalEntry>& entries, Job& job, ResultMerger& merger) {
  uint64_t merged = 0;
  for (const JournalEntry& e : entries) {
    if (e.epoch != job.epoch()) continue;  // merged before the job started again from nothing
    if (e.task_id >= job.num_tasks() || job.runtime(e.task_id).state == TaskState::kDone) continue;
    const TaskSpec& task = job.task(e.task_id);
    // No plausibility bound: a journaled result was accepted (possibly confirmed) before the crash.
    const CheckedResult checked =
        ResultMerger::Check(task, job.config().camera.width, job.config().image_height(), e.rgb_sums);
    if (!checked.valid) {
      spdlog::error("job {} task {}: journal entry invalid ({}); the task is re-run", job.id(), e.task_id,
                    checked.problem);
      continue;
    }
    merger.Merge(*checked.valid, job.accumulator());
    job.RecordMerge(e.task_id);
    job.MarkStored(e.task_id);  // it is in the journal
    ++merged;
  }
  return merged;
}

std::vector<std::string> SplitLines(const std::string& text) {
  std::vector<std::string> out;
  size_t begin = 0;
  while (begin < text.size()) {
    const size_t end = std::min(text.find('\n', begin), text.size());
    if (end > begin) out.push_back(text.substr(begin, end - begin));
    begin = end + 1;
  }
  return out;
}

enum class SetAsideResult { kAbsent, kMoved, kStuck };

// Moves a job's file out of recovery's way: to the first free name of `f` + suffix, then
// + suffix + ".1", ".2", … (a second upgrade must not overwrite the first one's results); removed
// if it cannot be moved. kStuck: it is still there, and resuming would read it.
SetAsideResult SetAside(const fs::path& f, const std::string& suffix) {
  std::error_code ec;
  if (!fs::exists(f, ec)) return SetAsideResult::kAbsent;
  for (int n = 0; n < 1000; ++n) {
    fs::path aside = f;
    aside += suffix;
    if (n > 0) aside += "." + std::to_string(n);
    if (fs::exists(aside, ec)) continue;
    fs::rename(f, aside, ec);
    if (!ec) return SetAsideResult::kMoved;
    break;
  }
  spdlog::error("{}: cannot be set aside; removing it", f.string());
  fs::remove(f, ec);
  return fs::exists(f, ec) ? SetAsideResult::kStuck : SetAsideResult::kMoved;
}

}  // namespace

// Checkpoints and journals whose job has no row (the job table was lost or restored from an
// older copy) belong to no job: they are never replayed into another job (job ids are random
// and never reused, jobs/random_id.h), but they are acknowledged results, so they are kept aside
// as `<file>.orphaned` and reported as an error for the operator.
static void SetAsideOrphans(const fs::path& checkpoint_dir, const std::vector<JobRow>& rows) {
  std::set<std::string> known;
  for (const JobRow& row : rows) {
    known.insert(Persister::CheckpointFile(checkpoint_dir, row.job_id).filename().string());
    known.insert(Persister::JournalFile(checkpoint_dir, row.job_id).filename().string());
  }
  std::error_code ec;
  for (fs::directory_iterator it(checkpoint_dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path file = it->path();
    const std::string ext = file.extension().string();
    if ((ext != ".acc" && ext != ".journal") || known.count(file.filename().string())) continue;
    fs::path aside = file;
    aside += ".orphaned";
    std::error_code rename_ec;
    fs::rename(file, aside, rename_ec);
    spdlog::error(
        "{} belongs to no known job (the job table was lost or restored?); not replayed, {} ",
        file.filename().string(),
        rename_ec ? "left in place: " + rename_ec.message() : "kept as " + aside.filename().string());
  }
}

// The seal a finished job's checkpoint must have: the row's, or — for a row stored before seals —
// as many tasks as its task rows call done (rows are written DONE only for stored results).
CheckpointSeal ExpectedSeal(const JobRow& row, uint64_t done_rows) {
  if (row.checkpoint.digest != 0) return row.checkpoint;
  return CheckpointSeal{done_rows, 0};
}

RecoveryReport RecoverJobs(JobStore& db, const SceneCatalog& scenes, const fs::path& checkpoint_dir,
                           Scheduler& scheduler, const Clock& clock, bool keep_other_builds) {
  RecoveryReport report;
  const double now = clock.Now();
  std::vector<JobRow> rows = db.LoadJobs();
  SetAsideOrphans(checkpoint_dir, rows);
  for (JobRow& row : rows) {
    scheduler.ReserveJobSeq(row.seq);
    bool finished = IsTerminal(row.state);
    JobConfig config;
    try {
      photonfarm::v1::JobSpec spec;
      if (!spec.ParseFromString(row.spec)) throw InputError("stored spec does not parse");
      // A progressive photon-map job stored before α was written explicitly (job_spec.cpp) left
      // it unset when it was the default of the time, 2/3: it resumes with that α.
      if (spec.plan().has_progressive() &&
          spec.settings().integrator() == photonfarm::v1::INTEGRATOR_PHOTONMAP &&
          !spec.settings().photon_map().has_progressive_alpha())
        spec.mutable_settings()->mutable_photon_map()->set_progressive_alpha(
            kStoredJobsUnsetProgressiveAlpha);
      config = ValidateJobSpec(spec, scenes);
    } catch (const std::exception& e) {
      if (!finished) {
        spdlog::error("job {}: cannot be resumed: {}", row.job_id, e.what());
        row.state = JobState::kFailed;
        row.failure_reason = std::string("cannot be resumed after a restart: ") + e.what();
        db.Apply({row}, {});
        ++report.jobs_failed;
      } else {
        spdlog::warn("job {}: finished job no longer loads ({}); not listed", row.job_id, e.what());
      }
      continue;
    }
    const fs::path cp_file = Persister::CheckpointFile(checkpoint_dir, row.job_id);
    const fs::path journal_file = Persister::JournalFile(checkpoint_dir, row.job_id);
    // A finished job is served from its checkpoint only if the file is the one its row was sealed
    // with (docs/farm.md "Durability"). If not (damaged, missing, an older file put back), the
    // results are lost: a SUCCEEDED job is rendered again from zero — its spec and seed give the
    // same image — and a failed or cancelled one keeps its state and answers DATA_LOSS.
    const uint64_t done_rows = db.CountTasks(row.job_id, TaskState::kDone);
    const CheckpointSeal expected_seal = ExpectedSeal(row, done_rows);
    bool rerender = false, image_ok = false;
    if (finished) {
      bool unreadable = false;
      const std::string problem = VerifyCheckpointFile(cp_file, expected_seal, nullptr, &unreadable);
      image_ok = problem.empty();
      if (unreadable) {
        // A file system error, not a lost image: served (or refused) when asked for, as it reads then.
        spdlog::error("job {}: its final image {}; the job stays {}", row.job_id, problem,
                      JobStateName(row.state));
      } else if (!problem.empty() && row.state == JobState::kSucceeded) {
        spdlog::error(
            "job {}: DATA LOSS: its final image {}; rendering it again from zero (same spec and seed: "
            "same image); the file is kept with the suffix .damaged",
            row.job_id, problem);
        for (const fs::path& f : {cp_file, journal_file}) SetAside(f, ".damaged");
        rerender = true;
        finished = false;
        row.state = JobState::kQueued;
        row.failure_reason.clear();
        ++report.jobs_rerendered;
      } else if (!problem.empty()) {
        spdlog::error("job {}: DATA LOSS: its stored image {}; the job stays {} and its image is not served",
                      row.job_id, problem, JobStateName(row.state));
        ++report.images_lost;
      }
    }
    // A checkpoint and a journal name merged tasks by id; under another version of the plan's
    // expansion the ids mean other tasks (task_plan.h, PlanExpansionVersion). And results merged
    // under another coordinator build came from that build's workers, which may trace other
    // photons or estimate differently (docs/farm.md, Upgrades). Either way the job restarts from
    // zero merges: its image stays right, all of its work is redone.
    const uint32_t stored_version = config.spec.plan().expansion_version();
    const uint32_t current_version = PlanExpansionVersion(config.plan);
    const std::string stored_build = config.spec.plan().build();
    const std::string& current_build = scheduler.options().build;
    const bool other_expansion = stored_version != current_version;
    const bool builds_differ = stored_build != current_build;
    const std::string build_named = stored_build.empty() ? "(unrecorded)" : limits::Quote(stored_build);
    const bool from_zero =
        rerender || (!finished && (other_expansion || (builds_differ && !keep_other_builds)));
    if (from_zero && !rerender) {
      const std::string suffix =
          other_expansion ? ".expansion-v" + std::to_string(stored_version) : std::string(".other-build");
      bool moved = false, stuck = false;
      for (const fs::path& f : {cp_file, journal_file}) {
        const SetAsideResult r = SetAside(f, suffix);
        moved = moved || r == SetAsideResult::kMoved;
        stuck = stuck || r == SetAsideResult::kStuck;
      }
      if (stuck) {
        // Its old results could be neither moved nor removed: resuming would merge them.
        spdlog::error("job {}: its merged results could not be set aside; the job fails", row.job_id);
        row.state = JobState::kFailed;
        row.failure_reason = "cannot be resumed after a restart: its old results could not be set aside";
        db.Apply({row}, {});
        ++report.jobs_failed;
        continue;
      }
      const std::string what =
          moved ? "its merged results (checkpoint, journal) are set aside with the suffix " + suffix +
                      " (or " + suffix + ".N) and its tasks re-run"
                : "it had merged nothing yet; its tasks run under this build";
      if (other_expansion) {
        spdlog::warn("job {}: created under plan expansion version {}, this coordinator's is {}: {}",
                     row.job_id, stored_version, current_version, what);
        ++report.jobs_reexpanded;
      } else {
        spdlog::warn(
            "job {}: submitted under build {}, this coordinator is '{}': {} (--allow-mixed-versions "
            "keeps them)",
            row.job_id, build_named, current_build, what);
        ++report.jobs_other_build;
      }
    } else if (!finished && builds_differ) {
      spdlog::warn(
          "job {}: submitted under build {}, resumed by '{}' (--allow-mixed-versions): its image mixes "
          "the two builds",
          row.job_id, build_named, current_build);
    }
    if (!finished && (other_expansion || builds_differ)) {
      // Stamped with this build from now on: a later restart of the same build resumes it.
      config.spec.mutable_plan()->set_expansion_version(current_version);
      config.spec.mutable_plan()->set_build(current_build);
      row.spec = config.spec.SerializeAsString();
      db.UpdateJobSpec(row.job_id, row.spec);
    }
    if (finished) {
      // Its counts, not its task list or task rows (docs/farm.md "Coordinator memory"): its final
      // checkpoint's seal says how many tasks were merged (the DONE rows, for a row from before
      // seals), every other task was cancelled when the job ended (Job::CancelAsJobEnds writes no
      // row for them). Tasks a dynamic plan created count when done.
      const uint64_t done = expected_seal.tasks;
      const uint64_t total = std::max(ScheduledTaskCount(config), done);
      auto job = Job::Finished(row.job_id, row.seq, std::make_shared<const JobConfig>(std::move(config)),
                               total, done, row.submitted_unix_ms);
      job->checkpoint_path = cp_file.string();
      job->RestoreState(row.state, row.failure_reason, now);
      job->RestoreElapsed(row.elapsed_seconds);
      // A row from before the column: its end estimated (it ran at least that long after submission).
      job->finished_unix_ms = row.finished_unix_ms != 0
                                  ? row.finished_unix_ms
                                  : row.submitted_unix_ms + int64_t(row.elapsed_seconds * 1000.0);
      job->stored_samples_merged = row.samples_merged;
      job->stored_noise_rms = row.noise_rms;
      job->checkpoint_seal = expected_seal;
      // Its verified final checkpoint holds it all; a journal is kept beside a lost image.
      std::error_code ec;
      if (image_ok) fs::remove(journal_file, ec);
      ++report.jobs_finished;
      scheduler.AddJob(std::move(job));
      continue;
    }

    const std::vector<TaskRow> task_rows = db.LoadTasks(row.job_id);
    std::vector<TaskSpec> tasks = ScheduledTasks(config);
    auto job =
        std::make_unique<Job>(row.job_id, row.seq, std::make_shared<const JobConfig>(std::move(config)),
                              std::move(tasks), row.submitted_unix_ms);
    job->checkpoint_path = cp_file.string();

    // A job rendered again from zero reads nothing of its lost image, even if it could not be set aside.
    // The job's epoch (restarts from nothing after a convicted worker, docs/farm.md "Result
    // verification") is the larger of its row's and its checkpoint's: the row may not have been
    // written after the restart's empty checkpoint, and a checkpoint older than the row's epoch
    // holds results the restart threw away. Journal entries of other epochs are not replayed.
    job->RestoreEpoch(from_zero ? 0 : row.epoch);
    std::vector<std::string> convicted = SplitLines(row.convicted);
    bool restart_from_checkpoint = false;  // the checkpoint is of a restart the row does not know
    try {
      CheckpointSeal seal;
      if (std::optional<Checkpoint> cp = rerender ? std::nullopt : ReadCheckpointFile(cp_file, &seal)) {
        std::string problem;
        if (!from_zero && cp->epoch < row.epoch)
          spdlog::warn("job {}: checkpoint of epoch {} is older than the job's restart (epoch {}): not used",
                       row.job_id, cp->epoch, row.epoch);
        else if (!ApplyCheckpoint(*cp, seal, *job, &problem))
          spdlog::error("job {}: checkpoint {} {}; restarting the job from zero merges", row.job_id,
                        cp_file.string(), problem);
        else {
          restart_from_checkpoint = !from_zero && cp->epoch > row.epoch;
          job->RestoreEpoch(cp->epoch);
          // A restart's checkpoint may be stored without its row: it names who was convicted too.
          for (const std::string& w : cp->convicted)
            if (std::find(convicted.begin(), convicted.end(), w) == convicted.end()) convicted.push_back(w);
        }
      }
    } catch (const std::exception& e) {
      spdlog::error("job {}: checkpoint unreadable ({}); restarting the job from zero merges", row.job_id,
                    e.what());
    }
    const uint64_t from_checkpoint = job->count(TaskState::kDone);
    const uint64_t journaled = rerender ? 0 : ReplayJournal(journal_file, *job, report);
    // The journal's entries go into the next checkpoint, which then empties the journal.
    if (journaled > 0) job->checkpoint_retry = true;
    job->dirty_tasks.clear();
    uint64_t acknowledged_lost = 0;
    // A task without a row is QUEUED (rows are written when a task first changes).
    std::vector<TaskState> row_state(job->num_tasks(), TaskState::kQueued);
    for (const TaskRow& t : task_rows) {
      if (t.task_id >= job->num_tasks()) continue;
      row_state[t.task_id] = t.state;
      TaskRuntime& rt = job->runtime(t.task_id);
      if (!from_zero) {  // a job re-run from zero starts its attempts afresh too
        rt.attempts = t.attempts;
        rt.failures = t.failures;
        rt.last_error = t.last_error;
        // A DONE row is written only for a stored result (persister.h, D2): one that neither the
        // checkpoint nor the journal holds was acknowledged and is lost.
        if (t.state == TaskState::kDone && rt.state != TaskState::kDone) ++acknowledged_lost;
      }
    }
    // Rows that differ from the recovered state are written again: a task leased before the
    // crash, and a task merged from the files whose DONE row had not been written (or had none).
    for (uint64_t id = 0; id < job->num_tasks(); ++id)
      if (job->runtime(id).state != row_state[id]) job->dirty_tasks.insert(id);
    if (acknowledged_lost > 0) {
      spdlog::error(
          "job {}: DATA LOSS: {} results acknowledged as stored are in neither the checkpoint nor the "
          "journal (files damaged, truncated or replaced?); those tasks are re-run, the image stays right",
          row.job_id, acknowledged_lost);
      report.acknowledged_lost += acknowledged_lost;
    }
    job->RestoreState(row.state, row.failure_reason, now);
    if (IsTerminal(row.state)) job->finished_unix_ms = row.finished_unix_ms;
    job->paused = row.paused;  // AddJob holds its tasks back (docs/farm.md "Pausing a job")
    // A restart's time budget starts anew (Job::Restart): the row's time is the dropped epoch's.
    job->RestoreElapsed(rerender || restart_from_checkpoint ? 0.0 : row.elapsed_seconds);
    if (rerender) {
      job->row_dirty = true;         // stored as QUEUED again
      job->dependencies_met = true;  // it succeeded before (scheduler_dependencies.cpp)
    }
    const uint64_t merged = job->count(TaskState::kDone);
    const uint64_t requeued = job->count(TaskState::kQueued);
    report.tasks_merged += merged;
    report.tasks_from_journal += journaled;
    report.tasks_requeued += requeued;
    ++report.jobs_resumed;
    spdlog::info(
        "job {}: resumed ({}): {} tasks merged ({} from the checkpoint, {} from the journal), {} queued",
        row.job_id, JobStateName(row.state), merged, from_checkpoint, journaled, requeued);
    scheduler.AddJob(std::move(job));
    scheduler.RestoreConvictions(row.job_id, convicted);
  }
  return report;
}

}  // namespace pf::server
