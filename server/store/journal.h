#pragma once
// The result journal: `<data-dir>/checkpoints/<job>.journal`, an append-only log of the results
// merged since the job's last checkpoint. With durable acknowledgements (--checkpoint-ms 0) a
// CompleteTask is answered once its entry is appended and fdatasync'ed — cheap (the task's own
// pixels), where rewriting the whole checkpoint per result would cost O(image). The checkpoint
// (server/store/checkpoint.h) stays the compact state; after each checkpoint the journal is
// truncated.
//
// Entry (little-endian):
//   "PFJ1"                    4-byte magic
//   u64 task_id
//   u32 n, n × f32            the rgb_sums exactly as received
//   u64 Checksum64 of the entry's preceding bytes
//
// Replay (recovery): checkpoint first, then every journal entry whose task is not merged yet, in
// file order; merging is order-independent, so the result equals the uninterrupted run. Reading
// stops at the first torn or corrupt entry and the file is cut back to the last good entry. A
// torn tail (a crash in the middle of an append: that result was never acknowledged) is normal;
// damage before the end (acknowledged results lost) is logged as an error, the file is kept as
// `<job>.journal.damaged`, and the lost tasks are re-run.

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace pf::server {

struct JournalEntry {
  uint64_t task_id = 0;
  std::vector<float> rgb_sums;
};

std::string EncodeJournalEntry(uint64_t task_id, std::span<const float> rgb_sums);

// Entries up to the first bad one; `valid_bytes` = the offset just after the last good entry.
// Missing file: no entries. SystemError if unreadable.
// `damaged` (optional) tells a torn tail from damage: appends are sequential, so at most the
// last entry can be incomplete after a crash. If a bad entry is followed by further bytes (its
// declared end lies before the end of the file, or another entry's magic follows), results
// that were acknowledged are unreadable: *damaged = true.
std::vector<JournalEntry> ReadJournalFile(const std::filesystem::path& file, uint64_t* valid_bytes,
                                          bool* damaged = nullptr);

}  // namespace pf::server
