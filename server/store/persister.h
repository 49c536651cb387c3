#pragma once
// Writes what the scheduler changed — results to the journal, accumulators to checkpoint files,
// task and job rows to SQLite — on its own thread, so that no RPC ever waits for a disk except on
// purpose (durable acknowledgements, below). The rules it keeps are docs/farm.md, "Durability":
//
//   D1  A result is acknowledged (CompleteTask: merged = true) only once it is stored: its entry is
//       in its job's journal and synced, or a checkpoint that holds it is written, synced and read
//       back equal. A result that can be stored nowhere is answered "not stored" (the worker is
//       not told it was merged) and its job gets no new leases until a checkpoint of it is stored.
//   D2  A DONE row is written only for a stored result; a finished job's final row only once its
//       final checkpoint is stored, and it carries that checkpoint's seal (task count, digest), so
//       an image is served or recovered only from the file the row names (recovery.h).
//   D3  The journal never holds a torn entry before a good one (JournalWriter), and is emptied only
//       after a verified checkpoint holds all of its entries.
//   D4  Every failure to write is retried at the next flush (about once a second) and shown in the
//       job's status; nothing is given up.
//
// One flush, in this order (all on the persister thread, so the orders are real):
//   1. append the queued results to their jobs' journals, fdatasync, then answer the CompleteTask
//      calls waiting for them;
//   2. write the checkpoints that are due (periodic, a journal grown past kJournalSnapshotBytes, a
//      finished job, a journal out of service, an earlier checkpoint that failed); after each one
//      is verified, empty its job's journal — every entry appended in step 1 was merged before the
//      checkpoint's snapshot was taken, so it is inside — and answer the calls that waited for it;
//   3. write the rows that may be written now (D2) in one SQLite transaction; remove the journals
//      of jobs whose final row is written.
// The checkpoint + journal are the authority on merged tasks; a task the database calls done but
// that neither holds is a lost acknowledged result (recovery.h logs it as DATA LOSS, re-runs it).
//
// Checkpoint interval (`--checkpoint-ms`), the trade-off:
//   0 (default)  durable acknowledgements (D1). Cost: an append of the task's own pixels (12 bytes
//                each) + one fdatasync per group of results arriving together. Checkpoints
//                (O(image)) every kSnapshotSeconds, when a job's journal exceeds
//                kJournalSnapshotBytes, and when a job finishes.
//   N > 0        no journal: CompleteTask answers merged = true at once (merged in memory, not yet
//                stored) and checkpoints are written at most every N ms. A crash loses the merges
//                of up to the last N ms: those tasks are re-run after the restart (never
//                double-counted). D2–D4 hold in both modes.

#include <condition_variable>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "common/core/file_layer.h"
#include "server/clock.h"
#include "server/store/job_store.h"
#include "server/store/journal.h"
#include "server/store/persist_source.h"

namespace pf::server {

inline constexpr double kSnapshotSeconds = 30;
inline constexpr uint64_t kJournalSnapshotBytes = uint64_t(64) << 20;
// Journals kept open between flushes; beyond it every journal's descriptor is closed after the
// flush (a reopen costs an open(2), not a read: JournalWriter::CloseFile).
inline constexpr size_t kMaxOpenJournals = 64;

class Persister {
 public:
  // Called once per result: with "" once it is stored, else with why it could not be.
  using Ack = std::function<void(const std::string& not_stored)>;

  // `files`: the system calls of the journal and checkpoint writes (tests inject faults there).
  Persister(PersistSource& source, JobStore& db, std::filesystem::path checkpoint_dir, const Clock& clock,
            double checkpoint_interval_seconds, FileLayer& files = SystemFiles());
  ~Persister();  // Stop()

  static std::filesystem::path CheckpointFile(const std::filesystem::path& checkpoint_dir,
                                              const std::string& job_id);
  static std::filesystem::path JournalFile(const std::filesystem::path& checkpoint_dir,
                                           const std::string& job_id);
  std::filesystem::path CheckpointFile(const std::string& job_id) const {
    return CheckpointFile(checkpoint_dir_, job_id);
  }
  const std::filesystem::path& checkpoint_dir() const { return checkpoint_dir_; }
  bool durable_acks() const { return interval_ <= 0; }

  void Start();
  // Final flush (everything, checkpoints included), then the thread ends. Returns false if the
  // final flush left something unstored (the coordinator then exits non-zero: what was not
  // stored is re-run at the next start). Idempotent (later calls return the first answer).
  bool Stop();
  // Stops the thread WITHOUT the final flush: what a crash would leave (tests). Queued
  // acknowledgements are answered "not stored" (their RPCs must finish for the server to stop).
  void Abandon();
  void Wake();

  // Durable mode: appends a merged result to its job's journal and calls `ack` once it is stored,
  // or with the reason it could not be (at once, "not stored", after Stop/Abandon). Copies the
  // floats.
  // `epoch`, `merge_seq`: the job's restart count and merge count when it was merged
  // (CompleteResult); a result of an earlier epoch than the job's is answered "not stored" and
  // never written; one that a stored checkpoint holds already is answered at once.
  void JournalThenAck(const std::string& job_id, uint64_t task_id, uint32_t epoch, uint64_t merge_seq,
                      std::span<const float> rgb_sums, Ack ack);

  // One synchronous flush on the calling thread (checkpoints_due forces checkpoints). True if
  // everything it tried to write was written.
  bool FlushNow(bool checkpoints_due = true);

  // Deletes a finished job's stored state (docs/farm.md "Deleting jobs"), with no flush running:
  // its rows first (a failure changes nothing; a crash after it leaves files that recovery sets
  // aside as orphaned, never a job), then `forget` (the job leaves memory: nothing of it is
  // collected again), then its results still waiting for the journal are answered "not stored"
  // and never written, and its files in the checkpoint directory — checkpoint, journal, and what
  // recovery set aside of them (<job>.*) — are removed. Returns the bytes removed.
  uint64_t DeleteJob(const std::string& job_id, const std::function<void()>& forget);

  uint64_t checkpoints_written() const;
  uint64_t journal_entries_written() const;

 private:
  struct Pending {
    std::string job_id;
    uint64_t task_id;
    uint32_t epoch;
    uint64_t merge_seq;
    std::vector<float> rgb_sums;
    Ack ack;
  };
  struct Waiting {  // an acknowledgement that waits for its job's checkpoint (step 2)
    std::string job_id;
    uint32_t epoch;
    uint64_t merge_seq;
    std::string journal_problem;
    Ack ack;
  };
  void Loop();
  bool Flush(bool force_checkpoints);
  // Step 1. Appends and syncs; returns the acks of stored entries in *stored, the others (their
  // job's journal failed) in *waiting.
  bool WriteJournal(std::vector<Pending>& pending, std::vector<Ack>* stored, std::vector<Waiting>* waiting);
  JournalWriter& Journal(const std::string& job_id);
  void CloseJournalsBeyondTheCap();
  void ReleasePending(const std::string& why);

  PersistSource& source_;
  JobStore& db_;
  std::filesystem::path checkpoint_dir_;
  const Clock& clock_;
  const double interval_;
  FileLayer& files_;

  std::mutex flush_mu_;  // one flush at a time; guards journals_
  std::map<std::string, std::unique_ptr<JournalWriter>> journals_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool woken_ = false;
  bool stop_ = false;
  bool started_ = false;
  bool stopped_ok_ = true;
  std::thread thread_;
  double last_checkpoint_;
  uint64_t checkpoints_written_ = 0;
  uint64_t journal_entries_written_ = 0;
  std::vector<Pending> pending_;
};

}  // namespace pf::server
