#include "server/store/sqlite_store.h"

#include <spdlog/spdlog.h>
#include <sqlite3.h>

#include <cerrno>
#include <set>

#include "common/core/error.h"

namespace pf::server {
namespace {

// A full or failing disk is a StorageError (the coordinator keeps serving and retries: docs/farm.md
// "Durability"); anything else a SystemError.
[[noreturn]] void Fail(int rc, const std::string& what) {
  switch (rc & 0xff) {
    case SQLITE_FULL:
      throw StorageError(what, ENOSPC);
    case SQLITE_IOERR:
    case SQLITE_CANTOPEN:
      throw StorageError(what, EIO);
    default:
      throw SystemError(what);
  }
}

constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);
INSERT OR IGNORE INTO meta(key, value) VALUES ('schema_version', '1');
CREATE TABLE IF NOT EXISTS scenes(
  hash TEXT PRIMARY KEY,
  entry TEXT NOT NULL,
  bytes INTEGER NOT NULL,
  files INTEGER NOT NULL,
  triangles INTEGER NOT NULL,
  lights INTEGER NOT NULL,
  default_camera BLOB NOT NULL,
  warnings TEXT NOT NULL,
  created_unix_ms INTEGER NOT NULL,
  max_emission REAL NOT NULL DEFAULT -1);
CREATE TABLE IF NOT EXISTS jobs(
  id TEXT PRIMARY KEY,
  seq INTEGER NOT NULL UNIQUE,
  spec BLOB NOT NULL,
  state INTEGER NOT NULL,
  failure_reason TEXT NOT NULL,
  submitted_unix_ms INTEGER NOT NULL,
  elapsed_seconds REAL NOT NULL,
  samples_merged INTEGER NOT NULL DEFAULT 0,
  noise_rms REAL NOT NULL DEFAULT -1,
  checkpoint_tasks INTEGER NOT NULL DEFAULT 0,
  checkpoint_digest TEXT NOT NULL DEFAULT '',
  epoch INTEGER NOT NULL DEFAULT 0,
  convicted TEXT NOT NULL DEFAULT '');
CREATE TABLE IF NOT EXISTS tasks(
  job_id TEXT NOT NULL,
  task_id INTEGER NOT NULL,
  state INTEGER NOT NULL,
  attempts INTEGER NOT NULL,
  failures INTEGER NOT NULL,
  last_error TEXT NOT NULL,
  PRIMARY KEY (job_id, task_id)) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS events(
  seq INTEGER PRIMARY KEY,
  job_id TEXT NOT NULL,
  event BLOB NOT NULL);
CREATE INDEX IF NOT EXISTS events_by_job ON events(job_id, seq);
CREATE TABLE IF NOT EXISTS workers(
  id TEXT PRIMARY KEY,
  info BLOB NOT NULL,
  last_seen_unix_ms INTEGER NOT NULL,
  quarantined_until_unix_s REAL NOT NULL);
)sql";

// A prepared statement, finalized on scope exit.
class Statement {
 public:
  Statement(sqlite3* db, const char* sql) : db_(db) {
    if (sqlite3_prepare_v2(db, sql, -1, &stmt_, nullptr) != SQLITE_OK)
      throw SystemError(std::string("sqlite: prepare '") + sql + "': " + sqlite3_errmsg(db));
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& Text(int i, const std::string& v) {
    Check(sqlite3_bind_text(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Statement& Blob(int i, const std::string& v) {
    Check(sqlite3_bind_blob(stmt_, i, v.data(), int(v.size()), SQLITE_TRANSIENT));
    return *this;
  }
  Statement& Int(int i, int64_t v) {
    Check(sqlite3_bind_int64(stmt_, i, v));
    return *this;
  }
  Statement& Real(int i, double v) {
    Check(sqlite3_bind_double(stmt_, i, v));
    return *this;
  }
  // true while a row is available.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Fail(rc, std::string("sqlite: step '") + sqlite3_sql(stmt_) + "': " + sqlite3_errmsg(db_));
  }
  void Run() {
    while (Step()) {
    }
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  std::string ColText(int i) {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(stmt_, i));
    return p ? std::string(p, size_t(sqlite3_column_bytes(stmt_, i))) : std::string();
  }
  std::string ColBlob(int i) {
    const auto* p = static_cast<const char*>(sqlite3_column_blob(stmt_, i));
    return p ? std::string(p, size_t(sqlite3_column_bytes(stmt_, i))) : std::string();
  }
  int64_t ColInt(int i) { return sqlite3_column_int64(stmt_, i); }
  double ColReal(int i) { return sqlite3_column_double(stmt_, i); }

 private:
  void Check(int rc) {
    if (rc != SQLITE_OK) throw SystemError(std::string("sqlite: bind: ") + sqlite3_errmsg(db_));
  }
  sqlite3* db_;
  sqlite3_stmt* stmt_ = nullptr;
};

// BEGIN IMMEDIATE … COMMIT, rolled back if an exception leaves the scope.
class Transaction {
 public:
  explicit Transaction(sqlite3* db) : db_(db) { Exec("BEGIN IMMEDIATE"); }
  ~Transaction() {
    if (!committed_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  void Commit() {
    Exec("COMMIT");
    committed_ = true;
  }

 private:
  void Exec(const char* sql) {
    char* err = nullptr;
    if (const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &err); rc != SQLITE_OK) {
      std::string msg = err ? err : "unknown error";
      sqlite3_free(err);
      Fail(rc, std::string("sqlite: ") + sql + ": " + msg);
    }
  }
  sqlite3* db_;
  bool committed_ = false;
};

void UpsertTask(Statement& st, const TaskRow& t) {
  st.Text(1, t.job_id)
      .Int(2, int64_t(t.task_id))
      .Int(3, int(t.state))
      .Int(4, t.attempts)
      .Int(5, t.failures)
      .Text(6, t.last_error)
      .Run();
}

constexpr const char* kUpsertTask =
    "INSERT INTO tasks(job_id, task_id, state, attempts, failures, last_error) VALUES (?1, ?2, ?3, ?4, ?5, "
    "?6) "
    "ON CONFLICT(job_id, task_id) DO UPDATE SET state = ?3, attempts = ?4, failures = ?5, last_error = ?6";

}  // namespace

SqliteStore::SqliteStore(const std::filesystem::path& db_file) : path_(db_file.string()) {
  if (sqlite3_open_v2(path_.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
                      nullptr) != SQLITE_OK) {
    const std::string msg = db_ ? sqlite3_errmsg(db_) : "out of memory";
    sqlite3_close(db_);
    throw SystemError(path_ + ": cannot open database: " + msg);
  }
  sqlite3_busy_timeout(db_, 5000);
  // Deleted jobs give their pages back to the file system (DeleteJob: incremental_vacuum; docs/farm.md
  // "Deleting jobs"). Set before the first table of a new database; one made before is converted
  // once, below.
  Exec("PRAGMA auto_vacuum = INCREMENTAL");
  Exec("PRAGMA journal_mode = WAL");
  Exec("PRAGMA synchronous = FULL");
  Exec("PRAGMA foreign_keys = ON");
  Exec(kSchema);
  // Databases from before the result bound lack scenes.max_emission: -1 = unknown (no upper
  // bound for jobs of those scenes; a new upload of the bundle does not change that) …
  AddColumnIfMissing("scenes", "max_emission", "REAL NOT NULL DEFAULT -1");
  // … and before --plan auto scenes.caustic_paths: -1 = unknown (auto assumes a caustic map) …
  AddColumnIfMissing("scenes", "caustic_paths", "INTEGER NOT NULL DEFAULT -1");
  // … and before checkpoint seals (docs/farm.md "Durability") jobs.checkpoint_tasks and
  // jobs.checkpoint_digest ('' = no seal recorded: recovery then checks the task rows instead),
  // and before result verification jobs.epoch and jobs.convicted (no restart, nobody convicted).
  AddColumnIfMissing("jobs", "checkpoint_tasks", "INTEGER NOT NULL DEFAULT 0");
  AddColumnIfMissing("jobs", "checkpoint_digest", "TEXT NOT NULL DEFAULT ''");
  AddColumnIfMissing("jobs", "epoch", "INTEGER NOT NULL DEFAULT 0");
  AddColumnIfMissing("jobs", "convicted", "TEXT NOT NULL DEFAULT ''");
  // … and before pf pause jobs.paused (none paused).
  AddColumnIfMissing("jobs", "paused", "INTEGER NOT NULL DEFAULT 0");
  // … and before pf purge jobs.finished_unix_ms (0: recovery estimates it).
  AddColumnIfMissing("jobs", "finished_unix_ms", "INTEGER NOT NULL DEFAULT 0");
  // A database from before incremental vacuuming: one VACUUM rewrites it with it (once; O(size)).
  int64_t auto_vacuum = 0;
  {
    Statement st(db_, "PRAGMA auto_vacuum");  // finalized before the VACUUM
    if (st.Step()) auto_vacuum = st.ColInt(0);
  }
  if (auto_vacuum != 2) {  // 2: incremental
    spdlog::info("{}: converting to incremental vacuuming (one VACUUM)", path_);
    Exec("VACUUM");
  }
}

SqliteStore::~SqliteStore() {
  sqlite3_close(db_);
}

void SqliteStore::AddColumnIfMissing(const std::string& table, const std::string& column,
                                     const std::string& declaration) {
  bool present = false;
  {
    Statement st(db_, ("SELECT name FROM pragma_table_info('" + table + "')").c_str());
    while (st.Step()) present |= st.ColText(0) == column;
  }
  if (!present) Exec(("ALTER TABLE " + table + " ADD COLUMN " + column + " " + declaration).c_str());
}

void SqliteStore::Exec(const char* sql) {
  char* err = nullptr;
  if (const int rc = sqlite3_exec(db_, sql, nullptr, nullptr, &err); rc != SQLITE_OK) {
    std::string msg = err ? err : "unknown error";
    sqlite3_free(err);
    Fail(rc, path_ + ": " + msg);
  }
}

void SqliteStore::PutScene(const SceneRow& s) {
  std::lock_guard lock(mu_);
  Statement(
      db_,
      "INSERT OR IGNORE INTO scenes(hash, entry, bytes, files, triangles, lights, default_camera, warnings, "
      "created_unix_ms, max_emission, caustic_paths) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)")
      .Text(1, s.hash)
      .Text(2, s.entry)
      .Int(3, int64_t(s.bytes))
      .Int(4, int64_t(s.files))
      .Int(5, int64_t(s.triangles))
      .Int(6, s.lights)
      .Blob(7, s.default_camera)
      .Text(8, s.warnings)
      .Int(9, s.created_unix_ms)
      .Real(10, s.max_emission)
      .Int(11, s.caustic_paths)
      .Run();
}

std::vector<SceneRow> SqliteStore::LoadScenes() {
  std::lock_guard lock(mu_);
  std::vector<SceneRow> out;
  Statement st(
      db_,
      "SELECT hash, entry, bytes, files, triangles, lights, default_camera, warnings, created_unix_ms, "
      "max_emission, caustic_paths FROM scenes ORDER BY created_unix_ms, hash");
  while (st.Step()) {
    SceneRow s;
    s.hash = st.ColText(0);
    s.entry = st.ColText(1);
    s.bytes = uint64_t(st.ColInt(2));
    s.files = uint64_t(st.ColInt(3));
    s.triangles = uint64_t(st.ColInt(4));
    s.lights = uint32_t(st.ColInt(5));
    s.default_camera = st.ColBlob(6);
    s.warnings = st.ColText(7);
    s.created_unix_ms = st.ColInt(8);
    s.max_emission = st.ColReal(9);
    s.caustic_paths = int(st.ColInt(10));
    out.push_back(std::move(s));
  }
  return out;
}

void SqliteStore::InsertJob(const JobRow& job, const std::vector<TaskRow>& tasks) {
  std::lock_guard lock(mu_);
  Transaction tx(db_);
  Statement(db_,
            "INSERT INTO jobs(id, seq, spec, state, failure_reason, submitted_unix_ms, elapsed_seconds) "
            "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)")
      .Text(1, job.job_id)
      .Int(2, int64_t(job.seq))
      .Blob(3, job.spec)
      .Int(4, int(job.state))
      .Text(5, job.failure_reason)
      .Int(6, job.submitted_unix_ms)
      .Real(7, job.elapsed_seconds)
      .Run();
  Statement task(db_, kUpsertTask);
  for (const TaskRow& t : tasks) UpsertTask(task, t);
  tx.Commit();
}

void SqliteStore::Apply(const std::vector<JobRow>& jobs, const std::vector<TaskRow>& tasks) {
  if (jobs.empty() && tasks.empty()) return;
  std::lock_guard lock(mu_);
  Transaction tx(db_);
  Statement job(db_,
                "UPDATE jobs SET state = ?2, failure_reason = ?3, elapsed_seconds = ?4, samples_merged = ?5, "
                "noise_rms = ?6, checkpoint_tasks = ?7, checkpoint_digest = ?8, epoch = ?9, convicted = ?10, "
                "finished_unix_ms = ?11 WHERE id = ?1");
  for (const JobRow& j : jobs)
    job.Text(1, j.job_id)
        .Int(2, int(j.state))
        .Text(3, j.failure_reason)
        .Real(4, j.elapsed_seconds)
        .Int(5, int64_t(j.samples_merged))
        .Real(6, j.noise_rms)
        .Int(7, int64_t(j.checkpoint.tasks))
        .Text(8, DigestText(j.checkpoint.digest))
        .Int(9, j.epoch)
        .Text(10, j.convicted)
        .Int(11, j.finished_unix_ms)
        .Run();
  Statement task(db_, kUpsertTask);
  for (const TaskRow& t : tasks) UpsertTask(task, t);
  tx.Commit();
}

void SqliteStore::UpdateJobSpec(const std::string& job_id, const std::string& spec) {
  std::lock_guard lock(mu_);
  Statement(db_, "UPDATE jobs SET spec = ?2 WHERE id = ?1").Text(1, job_id).Blob(2, spec).Run();
}

std::vector<JobRow> SqliteStore::LoadJobs() {
  std::lock_guard lock(mu_);
  std::vector<JobRow> out;
  Statement st(
      db_,
      "SELECT id, seq, spec, state, failure_reason, submitted_unix_ms, elapsed_seconds, samples_merged, "
      "noise_rms, checkpoint_tasks, checkpoint_digest, epoch, convicted, paused, finished_unix_ms FROM jobs "
      "ORDER BY seq");
  while (st.Step()) {
    JobRow j;
    j.job_id = st.ColText(0);
    j.seq = uint64_t(st.ColInt(1));
    j.spec = st.ColBlob(2);
    j.state = JobState(st.ColInt(3));
    j.failure_reason = st.ColText(4);
    j.submitted_unix_ms = st.ColInt(5);
    j.elapsed_seconds = st.ColReal(6);
    j.samples_merged = uint64_t(st.ColInt(7));
    j.noise_rms = st.ColReal(8);
    j.checkpoint.tasks = uint64_t(st.ColInt(9));
    j.checkpoint.digest = DigestFromText(st.ColText(10));
    j.epoch = uint32_t(st.ColInt(11));
    j.convicted = st.ColText(12);
    j.paused = st.ColInt(13) != 0;
    j.finished_unix_ms = st.ColInt(14);
    out.push_back(std::move(j));
  }
  return out;
}

std::vector<TaskRow> SqliteStore::LoadTasks(const std::string& job_id) {
  std::lock_guard lock(mu_);
  std::vector<TaskRow> out;
  Statement st(
      db_,
      "SELECT task_id, state, attempts, failures, last_error FROM tasks WHERE job_id = ?1 ORDER BY task_id");
  st.Text(1, job_id);
  while (st.Step()) {
    TaskRow t;
    t.job_id = job_id;
    t.task_id = uint64_t(st.ColInt(0));
    t.state = TaskState(st.ColInt(1));
    t.attempts = uint32_t(st.ColInt(2));
    t.failures = uint32_t(st.ColInt(3));
    t.last_error = st.ColText(4);
    out.push_back(std::move(t));
  }
  return out;
}

uint64_t SqliteStore::CountTasks(const std::string& job_id, TaskState state) {
  std::lock_guard lock(mu_);
  Statement st(db_, "SELECT COUNT(*) FROM tasks WHERE job_id = ?1 AND state = ?2");
  st.Text(1, job_id).Int(2, int(state));
  return st.Step() ? uint64_t(st.ColInt(0)) : 0;
}

void SqliteStore::DeleteJob(const std::string& job_id) {
  std::lock_guard lock(mu_);
  Transaction tx(db_);
  Statement(db_, "DELETE FROM tasks WHERE job_id = ?1").Text(1, job_id).Run();
  Statement(db_, "DELETE FROM events WHERE job_id = ?1").Text(1, job_id).Run();
  Statement(db_, "DELETE FROM jobs WHERE id = ?1").Text(1, job_id).Run();
  tx.Commit();
  // The freed pages leave the file: moved to its end and cut off (incremental_vacuum), then the WAL
  // is checkpointed into the database, which shrinks, and truncated. Best effort: the job is deleted
  // either way, and the next deletion frees what this one could not.
  try {
    Exec("PRAGMA incremental_vacuum");
    Exec("PRAGMA wal_checkpoint(TRUNCATE)");
  } catch (const std::exception& e) {
    spdlog::warn("job {}: the database did not shrink after its deletion: {}", job_id, e.what());
  }
}

void SqliteStore::SetJobPaused(const std::string& job_id, bool paused) {
  std::lock_guard lock(mu_);
  Statement(db_, "UPDATE jobs SET paused = ?2 WHERE id = ?1").Text(1, job_id).Int(2, paused ? 1 : 0).Run();
}

void SqliteStore::SaveActivity(const ActivityRecords& records, size_t max_events_per_job) {
  if (records.empty()) return;
  std::lock_guard lock(mu_);
  Transaction tx(db_);
  // Only for a job that has a row: a job deleted while its events were on their way keeps none.
  Statement event(
      db_, "INSERT INTO events(job_id, event) SELECT ?1, ?2 WHERE EXISTS (SELECT 1 FROM jobs WHERE id = ?1)");
  std::set<std::string> jobs;
  for (const ActivityRecords::Event& e : records.events) {
    event.Text(1, e.job_id).Blob(2, e.bytes).Run();
    jobs.insert(e.job_id);
  }
  // Each job keeps its newest events, as in memory (the older ones are counted there, not here).
  Statement prune(db_,
                  "DELETE FROM events WHERE job_id = ?1 AND seq <= (SELECT seq FROM events WHERE job_id = ?1 "
                  "ORDER BY seq DESC LIMIT 1 OFFSET ?2)");
  for (const std::string& job : jobs) prune.Text(1, job).Int(2, int64_t(max_events_per_job)).Run();
  Statement worker(db_,
                   "INSERT OR REPLACE INTO workers(id, info, last_seen_unix_ms, quarantined_until_unix_s) "
                   "VALUES (?1, ?2, ?3, ?4)");
  for (const ActivityRecords::Worker& w : records.workers)
    worker.Text(1, w.worker_id)
        .Blob(2, w.bytes)
        .Int(3, w.last_seen_unix_ms)
        .Real(4, w.quarantined_until_unix_s)
        .Run();
  Statement forget(db_, "DELETE FROM workers WHERE id = ?1");
  for (const std::string& id : records.forgotten_workers) forget.Text(1, id).Run();
  tx.Commit();
}

ActivityRecords SqliteStore::LoadActivity() {
  std::lock_guard lock(mu_);
  ActivityRecords out;
  Statement(db_, "DELETE FROM events WHERE job_id NOT IN (SELECT id FROM jobs)").Run();
  Statement events(db_, "SELECT job_id, event FROM events ORDER BY seq");
  while (events.Step()) out.events.push_back({events.ColText(0), events.ColBlob(1)});
  Statement workers(db_,
                    "SELECT id, info, last_seen_unix_ms, quarantined_until_unix_s FROM workers ORDER BY id");
  while (workers.Step())
    out.workers.push_back({workers.ColText(0), workers.ColBlob(1), workers.ColInt(2), workers.ColReal(3)});
  return out;
}

}  // namespace pf::server
