#pragma once
// What the persister (server/store/persister.h) needs from whoever owns the jobs: the state to
// write, and word back of what reached the disk. The Scheduler implements it; store/ depends on
// this interface only, never on scheduling/ (docs/design.md, layers).
//
// The answers drive the durability rules (docs/farm.md, "Durability"): a result is stored once it
// is in its job's journal or in a verified checkpoint; a DONE row is written only for a stored
// result; a finished job's final row waits for its final checkpoint; a job whose results cannot
// be stored gets no new leases until they can.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "server/store/records.h"

namespace pf::server {

class PersistSource {
 public:
  virtual ~PersistSource() = default;

  // Checkpoints of jobs with merges since their last one: of every such job when `due`, else only
  // of finished jobs and of jobs whose last checkpoint failed or that must be checkpointed now
  // (ForceCheckpoint). Also brings finished jobs' final noise estimates up to date.
  virtual std::vector<Checkpoint> CollectCheckpoints(bool due) = 0;
  // The checkpoint is on disk at `path` and read back equal (its seal): every task it lists is
  // stored, the job's storage error clears and a job paused for storage resumes.
  virtual void CheckpointStored(const Checkpoint& checkpoint, const CheckpointSeal& seal,
                                const std::string& path) = 0;
  // The checkpoint could not be written: collected again at the next flush.
  virtual void CheckpointNotStored(const std::string& job_id, uint64_t merge_seq,
                                   const std::string& reason) = 0;

  // How often the job started again from nothing (Job::Restart): a result merged under an
  // earlier count is dropped, never stored. 0 for an unknown job.
  virtual uint32_t JobEpoch(const std::string& job_id) = 0;
  // The merge_seq of the job's last stored checkpoint: a result whose merge came at or before it
  // is stored already (a checkpoint of merge_seq S holds the job's first S merges of its epoch).
  // For an unknown (deleted) job: the largest value — nothing of it is written any more.
  virtual uint64_t StoredMergeSeq(const std::string& job_id) = 0;
  // These merged results are in the job's journal, synced.
  virtual void ResultsJournaled(const std::string& job_id, std::span<const uint64_t> task_ids) = 0;
  // A result of the job could be stored nowhere: its job gets no new leases until a checkpoint of
  // it is stored; its next flush writes one.
  virtual void ResultsNotStored(const std::string& job_id, const std::string& reason) = 0;
  // The job's journal cannot take entries now (a failed write or sync): checkpoint it at the next
  // flush even if no checkpoint is due.
  virtual void ForceCheckpoint(const std::string& job_id) = 0;

  // Rows that changed since the last call and may be written now (see above).
  virtual RowBatch CollectRows() = 0;
  // The rows could not be written: handed out again next time; `reason` shown in the jobs' status.
  virtual void RowsNotStored(const RowBatch& rows, const std::string& reason) = 0;
  // The rows are written: a storage error of the rows' jobs that came from rows clears.
  virtual void RowsStored(const RowBatch& rows) = 0;
};

}  // namespace pf::server
