#pragma once
// The data dir's quota (pf-coordinator --data-quota; docs/farm.md "The data dir's quota"): when
// everything under --data-dir (database, checkpoints and final images, scenes, photon maps)
// holds more than kDataQuotaHighWater of the quota, finished jobs are deleted, the one that ended
// first first, as `pf delete` deletes them (their files and the photon maps no remaining job
// uses), until it holds at most kDataQuotaLowWater of it. Queued, running, paused and waiting jobs
// are never deleted; a quota that only they exceed is warned about once. The margin below the
// quota is room for what jobs write before the next measurement: the quota is the most the data
// dir holds, not the point where deleting starts.

#include <cstdint>
#include <filesystem>

namespace pf::server {

inline constexpr double kDataQuotaHighWater = 0.85;
inline constexpr double kDataQuotaLowWater = 0.7;
// The data dir is measured at most this often (or ten times as long as the last measurement took,
// if longer: a large store is not walked back to back), and only after jobs changed (a merge, a
// state change), or once every kRetentionCheckSeconds.
inline constexpr double kDataQuotaCheckSeconds = 0.05;

// The bytes of every regular file under `dir`, recursively (entries that vanish or cannot be
// read while it walks are skipped, the rest still counted: jobs write and delete files meanwhile).
uint64_t DirectoryBytes(const std::filesystem::path& dir);

}  // namespace pf::server
