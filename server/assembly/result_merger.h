#pragma once
// Merging task results into a job's Accumulator (docs/design.md, §1 Merge).
//
// A result is validated once, where it enters the coordinator (Scheduler::Complete for a
// worker's result, recovery for a journal entry), before anything is changed: 3 finite,
// non-negative floats per pixel of the task's subset (the count from CountPixels, so a wrong size
// is caught without materialising pixels), within the accumulator's range and the job's
// plausibility bound (Accumulator::ValidateTaskResult). An invalid result is rejected whole; the
// scheduler then re-queues the task (attempt + 1) and logs the reason. An implausible one (above
// the bound) is rejected the same way unless it is a bit-identical second delivery by another
// worker. Check returns a ValidResult, the only thing Merge accepts: so a result cannot be merged
// unchecked, and Merge (and Accumulator::AddValidated under it) do not check it again.
//
// Merging needs the subset's pixel indices in subset order (PixelsOf). For skipping tasks those
// come from a permutation of all W·H pixels shared by the S² tasks of a round; the merger keeps
// the last few permutations so a round costs one permutation, not S².
//
// Thread-safe: Check and Merge are static, and the permutation cache has its own lock (the
// Scheduler calls PixelsOfTask off its global lock, from many threads at once).

#include <cstdint>
#include <limits>
#include <list>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "common/plan/accumulator.h"
#include "common/plan/task_plan.h"

namespace pf::server {

// A task result that passed ResultMerger::Validate. Views `task` and the sums: use it while they
// live (within one Complete or one journal entry).
class ValidResult {
 public:
  const TaskSpec& task() const { return *task_; }
  std::span<const float> rgb_sums() const { return rgb_sums_; }

 private:
  friend class ResultMerger;
  ValidResult(const TaskSpec& task, std::span<const float> rgb_sums) : task_(&task), rgb_sums_(rgb_sums) {}
  const TaskSpec* task_;
  std::span<const float> rgb_sums_;
};

// Check's answer: a ValidResult, or why there is none.
struct CheckedResult {
  std::optional<ValidResult> valid;
  std::string problem;  // set iff !valid
  ResultCheck::Verdict verdict = ResultCheck::Verdict::kOk;
};

class ResultMerger {
 public:
  explicit ResultMerger(size_t cached_permutations = 4) : capacity_(cached_permutations) {}

  // Whether `rgb_sums` may be merged for `task` of a width × height job
  // (Accumulator::ValidateTaskResult; `max_sample_radiance` is JobConfig::max_sample_radiance).
  static ResultCheck Validate(const TaskSpec& task, int width, int height, std::span<const float> rgb_sums,
                              double max_sample_radiance = std::numeric_limits<double>::infinity());

  // SHA-256 of the result's bytes: an implausible result is merged only when another worker
  // delivers the same digest (deterministic rendering makes an honest re-run bit-identical).
  static std::string Digest(std::span<const float> rgb_sums);

  // Validate, with the result wrapped for Merge when it passes. Without a bound (infinity) for a
  // result whose implausibility was confirmed, and for journal entries (checked when they came in).
  static CheckedResult Check(const TaskSpec& task, int width, int height, std::span<const float> rgb_sums,
                             double max_sample_radiance = std::numeric_limits<double>::infinity());

  // Adds a checked result to `acc` (of the job the result was checked for).
  void Merge(const ValidResult& result, Accumulator& acc);
  // The same with the task's pixels already computed (PixelsOfTask, each < width · height).
  static void Merge(const ValidResult& result, std::span<const uint32_t> pixels, Accumulator& acc);

  // The pixel indices of `task`'s subset (cached permutations for skipping).
  std::vector<uint32_t> PixelsOfTask(const TaskSpec& task, int width, int height);

 private:
  struct CachedPermutation {
    uint64_t seed;
    int width, height;
    std::shared_ptr<const std::vector<uint32_t>> perm;
  };
  std::shared_ptr<const std::vector<uint32_t>> Permutation(uint64_t seed, int width, int height);
  size_t capacity_;
  std::mutex cache_mu_;
  std::list<CachedPermutation> cache_;  // most recent first
};

}  // namespace pf::server
