#pragma once
// Where jobs and their tasks are stored: what scheduling (submission, recovery) and the persister
// need of the coordinator's database, and nothing of how it is kept. SqliteStore
// (server/store/sqlite_store.h) implements it; scheduling/ depends on this interface only, as
// store/ depends only on PersistSource (persist_source.h), never on scheduling/ (docs/design.md,
// S10 "Layers point one way").
//
// Every call is durable when it returns (a committed transaction) or throws: StorageError when the
// disk is full or failing, SystemError otherwise — the caller decides what is lost (nothing: a job
// whose row could not be inserted is not scheduled; rows that could not be written are handed out
// again, docs/farm.md "Durability").

#include <cstdint>
#include <string>
#include <vector>

#include "server/store/records.h"

namespace pf::server {

class JobStore {
 public:
  virtual ~JobStore() = default;

  // The job row and all its task rows, in one transaction.
  virtual void InsertJob(const JobRow& job, const std::vector<TaskRow>& tasks) = 0;
  // Updates of existing rows, in one transaction (jobs: state, failure reason, elapsed time,
  // samples merged, noise; tasks: upserted).
  virtual void Apply(const std::vector<JobRow>& jobs, const std::vector<TaskRow>& tasks) = 0;
  // Replaces a job's stored spec (recovery: a job re-expanded under this coordinator's plan
  // expansion version, recovery.cpp).
  virtual void UpdateJobSpec(const std::string& job_id, const std::string& spec) = 0;
  virtual std::vector<JobRow> LoadJobs() = 0;                             // in submission order
  virtual std::vector<TaskRow> LoadTasks(const std::string& job_id) = 0;  // by task id
  // How many of the job's task rows are in `state` (recovery of a finished job: its rows are not
  // loaded, docs/farm.md "Coordinator memory").
  virtual uint64_t CountTasks(const std::string& job_id, TaskState state) = 0;
  // Removes the job's row and all its task rows in one transaction: recovery, which starts from
  // the rows, never sees the job again. An unknown id is no error. The store's half of deleting a
  // job (Persister::DeleteJob; docs/farm.md "Deleting jobs").
  virtual void DeleteJob(const std::string& job_id) = 0;
  // Stores whether a user paused the job (PauseJob / ResumeJob): recovery restores it.
  virtual void SetJobPaused(const std::string& job_id, bool paused) = 0;
};

}  // namespace pf::server
