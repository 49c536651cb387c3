#pragma once
// The result journal: `<data-dir>/checkpoints/<job>.journal`, an append-only log of the results
// merged since the job's last checkpoint. With durable acknowledgements (--checkpoint-ms 0) a
// CompleteTask is answered once its entry is appended and fdatasync'ed — cheap (the task's own
// pixels), where rewriting the whole checkpoint per result would cost O(image). The checkpoint
// (server/store/checkpoint.h) stays the compact state; after each checkpoint the journal is
// truncated.
//
// Entry (little-endian):
//   "PFJ2"                    4-byte magic
//   u64 task_id
//   u32 epoch                 the job's restart count when the result was merged (Job::epoch)
//   u32 n, n × f32            the rgb_sums exactly as received
//   u64 Checksum64 of the entry's preceding bytes
// ("PFJ1" entries, from before epochs, have no epoch field and read as epoch 0.)
//
// Replay (recovery): checkpoint first, then every journal entry of the job's epoch whose task is
// not merged yet, in file order; merging is order-independent, so the result equals the
// uninterrupted run. An entry of an earlier epoch was merged before the job started again from
// nothing (a convicted worker, docs/farm.md "Result verification") and is never replayed. Reading
// stops at the first torn or corrupt entry and the file is cut back to the last good entry. A
// torn tail (a crash in the middle of an append: that result was never acknowledged) is normal;
// damage before the end (acknowledged results lost) is logged as an error, the file is kept as
// `<job>.journal.damaged`, and the lost tasks are re-run.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/file_layer.h"

namespace pf::server {

struct JournalEntry {
  uint64_t task_id = 0;
  uint32_t epoch = 0;
  std::vector<float> rgb_sums;
};

std::string EncodeJournalEntry(uint64_t task_id, uint32_t epoch, std::span<const float> rgb_sums);

// Entries up to the first bad one; `valid_bytes` = the offset just after the last good entry.
// Missing file: no entries. SystemError if unreadable.
// `damaged` (optional) tells a torn tail from damage: appends are sequential, so at most the
// last entry can be incomplete after a crash. If a bad entry is followed by further bytes (its
// declared end lies before the end of the file, or another entry's magic follows), results
// that were acknowledged are unreadable: *damaged = true.
std::vector<JournalEntry> ReadJournalFile(const std::filesystem::path& file, uint64_t* valid_bytes,
                                          bool* damaged = nullptr);

// Appends entries to one job's journal, through a FileLayer, and never after a bad byte: an entry
// that could not be written whole is cut off again, so an entry that follows it is readable (a
// torn entry followed by good ones would read as damage, and hide them). If the cut fails too, or
// a sync fails (after a failed fdatasync the kernel may have dropped the unsynced pages, so the
// file's content is unknown), the writer is *broken*: it takes no entry until Reset, after a
// verified checkpoint holds everything the file did, removes the file. Not thread-safe (the
// persister's flush lock guards it).
class JournalWriter {
 public:
  JournalWriter(std::filesystem::path file, FileLayer& files);
  ~JournalWriter();
  JournalWriter(const JournalWriter&) = delete;
  JournalWriter& operator=(const JournalWriter&) = delete;

  // False, with the reason, if the entry is not in the file (nor any part of it, unless broken).
  bool Append(std::string_view entry, std::string* problem);
  // fdatasync of the entries appended since the last sync; false (and broken) if it fails.
  bool Sync(std::string* problem);
  // Every entry is held by a verified checkpoint: empties the journal (or, if broken, removes the
  // file). False if that fails; the entries left behind are harmless: replay skips merged tasks
  // and entries of an earlier epoch.
  bool Reset(std::string* problem);
  // Closes and removes the file (the job is finished and its final checkpoint verified).
  void Remove();
  // Closes the file but remembers where its last good entry ends: the next Append reopens it
  // without reading it again (a coordinator with thousands of jobs must not hold a descriptor
  // for each).
  void CloseFile();
  bool open() const { return fd_ >= 0; }

  bool broken() const { return broken_; }
  uint64_t bytes_since_reset() const { return appended_; }

 private:
  bool Open(std::string* problem);
  void Break();
  std::filesystem::path file_;
  FileLayer& files_;
  int fd_ = -1;
  uint64_t end_ = 0;        // offset just after the last good entry
  bool end_known_ = false;  // end_ is the file's (it was opened by this writer before)
  uint64_t appended_ = 0;   // bytes appended since the last reset
  bool broken_ = false;
};

}  // namespace pf::server
