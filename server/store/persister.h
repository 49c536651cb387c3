#pragma once
// Writes what the scheduler changed — task and job rows to SQLite, results to the journal,
// accumulators to checkpoint files — on its own thread, so that no RPC ever waits for a disk
// except on purpose (durable acknowledgements, below).
//
// One flush, in this order (all on the persister thread, so the orders are real):
//   1. append the queued results to their jobs' journals (server/store/journal.h), fdatasync,
//      then answer the CompleteTask calls waiting for them;
//   2. if checkpoints are due: write the checkpoint of every job with new merges
//      (server/store/checkpoint.h) and truncate its journal — every entry appended in step 1 was
//      merged before the checkpoint's snapshot was taken, so it is inside;
//   3. write the changed rows in one SQLite transaction.
// The checkpoint + journal are the authority on merged tasks; a task the database calls done but
// that neither holds is re-run after a crash (recovery.h).
//
// Checkpoint interval (`--checkpoint-ms`), the trade-off:
//   0 (default)  durable acknowledgements: CompleteTask answers merged = true only once the
//                result is in the journal on disk (group commit: results arriving during one
//                fdatasync share the next). A crash never loses an acknowledged result. Cost:
//                an append of the task's own pixels (12 bytes each) + one fdatasync per group.
//                Checkpoints (O(image)) are written every kSnapshotSeconds, when a job's journal
//                exceeds kJournalSnapshotBytes, and when a job finishes.
//   N > 0        no journal: CompleteTask answers at once and checkpoints are written at most
//                every N ms. A crash loses the merges of up to the last N ms: those tasks are
//                re-run after the restart (never double-counted).
// A job that finishes is checkpointed at once in both modes, before its final row is written.

#include <condition_variable>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "server/scheduling/clock.h"
#include "server/scheduling/scheduler.h"
#include "server/store/sqlite_store.h"

namespace pf::server {

inline constexpr double kSnapshotSeconds = 30;
inline constexpr uint64_t kJournalSnapshotBytes = uint64_t(64) << 20;

class Persister {
 public:
  Persister(Scheduler& scheduler, SqliteStore& db, std::filesystem::path checkpoint_dir, const Clock& clock,
            double checkpoint_interval_seconds);
  ~Persister();  // Stop()

  static std::filesystem::path CheckpointFile(const std::filesystem::path& checkpoint_dir,
                                              const std::string& job_id);
  static std::filesystem::path JournalFile(const std::filesystem::path& checkpoint_dir,
                                           const std::string& job_id);
  std::filesystem::path CheckpointFile(const std::string& job_id) const {
    return CheckpointFile(checkpoint_dir_, job_id);
  }
  bool durable_acks() const { return interval_ <= 0; }

  void Start();
  // Final flush (everything, checkpoints included), then the thread ends. Idempotent.
  void Stop();
  // Stops the thread WITHOUT the final flush: what a crash would leave (tests). Queued
  // acknowledgements run (their RPCs must finish for the server to stop).
  void Abandon();
  void Wake();

  // Durable mode: appends a merged result to its job's journal and runs `ack` once it is on disk
  // (at once after Stop/Abandon). The floats are copied.
  void JournalThenAck(const std::string& job_id, uint64_t task_id, std::span<const float> rgb_sums,
                      std::function<void()> ack);

  // One synchronous flush on the calling thread (checkpoints_due forces checkpoints).
  void FlushNow(bool checkpoints_due = true);

  uint64_t checkpoints_written() const;
  uint64_t journal_entries_written() const;

 private:
  struct Pending {
    std::string job_id;
    uint64_t task_id;
    std::vector<float> rgb_sums;
    std::function<void()> ack;
  };
  struct JournalState {
    int fd = -1;
    uint64_t bytes = 0;  // appended since the last checkpoint
  };
  void Loop();
  void Flush(bool force_checkpoints);
  // Appends, fdatasyncs; returns the acks of the written entries and the jobs that failed.
  void WriteJournal(std::vector<Pending>& pending, std::vector<std::function<void()>>* acks,
                    std::vector<std::function<void()>>* after_checkpoint, bool* force_checkpoints);
  void TruncateJournal(const std::string& job_id);
  void CloseJournal(const std::string& job_id, bool remove);
  void ReleasePending();

  Scheduler& scheduler_;
  SqliteStore& db_;
  std::filesystem::path checkpoint_dir_;
  const Clock& clock_;
  const double interval_;

  std::mutex flush_mu_;  // one flush at a time; guards journals_
  std::map<std::string, JournalState> journals_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool woken_ = false;
  bool stop_ = false;
  bool started_ = false;
  std::thread thread_;
  double last_checkpoint_;
  uint64_t checkpoints_written_ = 0;
  uint64_t journal_entries_written_ = 0;
  std::vector<Pending> pending_;
};

}  // namespace pf::server
