#pragma once
// The rows and files the coordinator persists (docs/farm.md, "Coordinator: SQLite schema" and
// "checkpoint format"). Produced by the scheduler (what changed), written by the persister,
// read back by recovery. Plain data: no locks, no I/O.

#include <cstdint>
#include <string>
#include <vector>

namespace pf::server {

// Numeric values stored in SQLite; never renumber (they are on disk).
enum class JobState : int { kQueued = 1, kRunning = 2, kSucceeded = 3, kFailed = 4, kCancelled = 5 };
enum class TaskState : int { kQueued = 1, kLeased = 2, kDone = 3, kCancelled = 4 };

const char* JobStateName(JobState s);
const char* TaskStateName(TaskState s);
bool IsTerminal(JobState s);

// What identifies the content of a checkpoint file (server/store/checkpoint.h): how many tasks
// it holds and the checksum its last 8 bytes carry, a digest of all the bytes before them. The
// row of a job keeps the seal of its last verified checkpoint; a finished job's image is served
// or recovered only from a file with that seal (docs/farm.md, "Durability").
struct CheckpointSeal {
  uint64_t tasks = 0;
  uint64_t digest = 0;  // 0: none (no checkpoint yet, or a row stored before seals existed)
  bool operator==(const CheckpointSeal&) const = default;
};
// A digest as 16 hex digits ("" for 0), as the jobs table stores it (SQLite integers are signed);
// anything but 16 hex digits reads as 0.
std::string DigestText(uint64_t digest);
uint64_t DigestFromText(const std::string& text);

struct JobRow {
  std::string job_id;
  uint64_t seq = 0;  // submission order (also the number in the id)
  std::string spec;  // serialized photonfarm.v1.JobSpec, normalised (camera resolved)
  JobState state = JobState::kQueued;
  std::string failure_reason;
  int64_t submitted_unix_ms = 0;
  double elapsed_seconds = 0;   // running time accumulated so far
  uint64_t samples_merged = 0;  // for the status of finished jobs (their accumulator stays on disk)
  double noise_rms = -1;
  CheckpointSeal checkpoint = {};  // of the job's last verified checkpoint
  // Restarts from nothing (Job::epoch) and the workers convicted of wrong results, '\n'-separated
  // (docs/farm.md, "Result verification"): recovery keeps both.
  uint32_t epoch = 0;
  std::string convicted = {};
  // Paused by a user (PauseJob, docs/farm.md "Pausing a job"): written by JobStore::SetJobPaused
  // only, read by recovery.
  bool paused = false;
  // When the job reached its terminal state (Job::finished_unix_ms); 0 while active, and in rows
  // written before the column (recovery then estimates it: submitted + elapsed).
  int64_t finished_unix_ms = 0;
};

struct TaskRow {
  std::string job_id;
  uint64_t task_id = 0;
  TaskState state = TaskState::kQueued;
  uint32_t attempts = 0;  // leases handed out so far (the next lease is attempt attempts+1)
  uint32_t failures = 0;  // attempts that ended badly (lease expired, FailTask, rejected result)
  std::string last_error;
};

struct SceneRow {
  std::string hash;
  std::string entry;
  uint64_t bytes = 0;
  uint64_t files = 0;
  uint64_t triangles = 0;
  uint32_t lights = 0;
  std::string default_camera;  // serialized photonfarm.v1.Camera: manifest camera or DefaultCamera
  std::string warnings;        // loader warnings, '\n'-separated
  int64_t created_unix_ms = 0;
  double max_emission = -1;  // the brightest emitter's largest channel (Le); -1 = unknown
  int caustic_paths = -1;    // 1 / 0: the scene has specular or glossy surfaces; -1 = unknown
};

// One checkpoint file: the accumulator and the ids of exactly the tasks merged into it.
struct Checkpoint {
  std::string job_id;
  uint64_t merge_seq = 0;                 // number of merges it contains (monotonic per job)
  std::vector<uint64_t> merged_task_ids;  // ascending
  std::string accumulator;                // Accumulator::Serialize()
  uint32_t epoch = 0;                     // the job's restart count (Job::epoch) when it was taken
  std::vector<std::string> convicted;     // the job's convicted workers then (Job::convicted_workers)
};

// The rows that changed since the last flush.
struct RowBatch {
  std::vector<JobRow> jobs;
  std::vector<TaskRow> tasks;
  bool empty() const { return jobs.empty() && tasks.empty(); }
};

}  // namespace pf::server
