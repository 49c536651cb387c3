#pragma once
// Checkpoint files: `<data-dir>/checkpoints/<job>.acc`, one per job, holding the job's
// Accumulator *and* the ids of exactly the tasks merged into it — in one file, so the two can
// never disagree: after a crash a task is either in the checkpoint (merged, not re-run) or not
// (re-run), never counted twice.
//
// Format (little-endian):
//   "PFCKPT01"                          8-byte magic
//   u32 version = 3                     (1: no epoch, read as 0; 2: no convicted workers)
//   u32 len, job id bytes
//   u64 merge_seq                       merges contained (monotonic per job)
//   u32 epoch                           the job's restart count (Job::epoch)
//   u32 len, bytes                      the job's convicted workers, one per line
//   u64 n, u64 × n merged task ids      ascending
//   u64 len, accumulator bytes          Accumulator::Serialize()
//   u64 Checksum64 (server/store/checksum.h) of all preceding bytes
//
// Writing is atomic (common/core/atomic_file.h): a reader sees the old or the new checkpoint,
// never a torn one. Bytes go through common/core/byte_codec.h.

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "common/core/file_layer.h"
#include "server/store/records.h"

namespace pf::server {

std::string EncodeCheckpoint(const Checkpoint& checkpoint);
// Throws InputError ("checkpoint: ...") if the bytes are not a valid checkpoint. `seal`
// (optional): what identifies these bytes (records.h).
Checkpoint DecodeCheckpoint(std::string_view bytes, CheckpointSeal* seal = nullptr);

// Writes the file atomically and durably through `files`, reads it back and checks that it holds
// exactly the bytes written; returns their seal. StorageError if any step fails (the old file,
// if any, is then still in place).
CheckpointSeal WriteCheckpointFile(const std::filesystem::path& file, const Checkpoint& checkpoint,
                                   FileLayer& files = SystemFiles());
// nullopt if the file does not exist; InputError if it is corrupt; SystemError if unreadable.
std::optional<Checkpoint> ReadCheckpointFile(const std::filesystem::path& file,
                                             CheckpointSeal* seal = nullptr);

// The file at `file` is the checkpoint `expected` names (same task count and digest), else
// DataLossError-worthy text: "" if it is, else why not ("missing", "damaged (…)", "holds 7 tasks,
// 96 expected", "is another checkpoint (digest …)"). A seal of 0 tasks expects no file or an
// empty one. On success `checkpoint` (optional) receives the decoded file. `unreadable`
// (optional) tells a file system that failed to read it (the file may be fine: retry later) from
// a file that is not the sealed one.
std::string VerifyCheckpointFile(const std::filesystem::path& file, const CheckpointSeal& expected,
                                 std::optional<Checkpoint>* checkpoint = nullptr, bool* unreadable = nullptr);

}  // namespace pf::server
