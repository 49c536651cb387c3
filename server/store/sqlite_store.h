#pragma once
// The coordinator's database: `<data-dir>/coordinator.db` (SQLite, WAL journal,
// synchronous=FULL: a committed transaction survives a crash of the process or the machine).
// Schema (docs/farm.md, "Coordinator: SQLite schema"):
//
//   meta(key TEXT PRIMARY KEY, value TEXT)               schema_version = 1
//   scenes(hash TEXT PRIMARY KEY, entry, bytes, files, triangles, lights,
//          default_camera BLOB, warnings TEXT, created_unix_ms)
//   jobs(id TEXT PRIMARY KEY, seq INTEGER UNIQUE, spec BLOB, state INTEGER, failure_reason,
//        submitted_unix_ms, elapsed_seconds, samples_merged, noise_rms,
//        checkpoint_tasks, checkpoint_digest,    the seal of the job's last stored checkpoint
//        epoch, convicted)                       restarts from nothing, convicted workers
//   tasks(job_id, task_id, state INTEGER, attempts, failures, last_error,
//         PRIMARY KEY (job_id, task_id)) WITHOUT ROWID
//
// Accumulators are not in the database but in checkpoint files (server/store/checkpoint.h): the
// checkpoint is the authority on which tasks are merged; `tasks.state` is informational for
// merged tasks and authoritative for attempts/failures.
//
// Thread-safe (one connection behind a mutex). Errors are SystemError naming the statement;
// StorageError when the disk is full or failing (SQLITE_FULL, SQLITE_IOERR).

#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "server/store/activity_store.h"
#include "server/store/job_store.h"
#include "server/store/records.h"

struct sqlite3;

namespace pf::server {

class SqliteStore final : public JobStore, public ActivityStore {
 public:
  // Opens (creating if needed) the database file and its schema.
  explicit SqliteStore(const std::filesystem::path& db_file);
  ~SqliteStore() override;
  SqliteStore(const SqliteStore&) = delete;
  SqliteStore& operator=(const SqliteStore&) = delete;

  void PutScene(const SceneRow& scene);  // insert or ignore (content-addressed)
  std::vector<SceneRow> LoadScenes();

  // JobStore (server/store/job_store.h).
  void InsertJob(const JobRow& job, const std::vector<TaskRow>& tasks) override;
  void Apply(const std::vector<JobRow>& jobs, const std::vector<TaskRow>& tasks) override;
  void UpdateJobSpec(const std::string& job_id, const std::string& spec) override;
  std::vector<JobRow> LoadJobs() override;
  std::vector<TaskRow> LoadTasks(const std::string& job_id) override;
  uint64_t CountTasks(const std::string& job_id, TaskState state) override;
  void DeleteJob(const std::string& job_id) override;
  void SetJobPaused(const std::string& job_id, bool paused) override;

  // ActivityStore (server/store/activity_store.h).
  void SaveActivity(const ActivityRecords& records, size_t max_events_per_job) override;
  ActivityRecords LoadActivity() override;

 private:
  void Exec(const char* sql);
  void AddColumnIfMissing(const std::string& table, const std::string& column,
                          const std::string& declaration);
  std::mutex mu_;
  sqlite3* db_ = nullptr;
  std::string path_;
};

}  // namespace pf::server
