#include "server/assembly/result_merger.h"

#include "common/core/error.h"

namespace pf::server {

std::string ResultMerger::Validate(const TaskSpec& task, int width, int height,
                                   std::span<const float> rgb_sums) {
  if (task.sample_end <= task.sample_begin) return "task: empty sample range";
  const uint64_t pixels = CountPixels(task.pixels, width, height);
  return Accumulator::ValidateTaskResult(rgb_sums, pixels, task.sample_end - task.sample_begin);
}

std::shared_ptr<const std::vector<uint32_t>> ResultMerger::Permutation(uint64_t seed, int width, int height) {
  for (auto it = cache_.begin(); it != cache_.end(); ++it) {
    if (it->seed == seed && it->width == width && it->height == height) {
      cache_.splice(cache_.begin(), cache_, it);
      return cache_.front().perm;
    }
  }
  auto perm = std::make_shared<const std::vector<uint32_t>>(
      PixelPermutation(seed, uint32_t(width) * uint32_t(height)));
  cache_.push_front({seed, width, height, perm});
  while (cache_.size() > capacity_) cache_.pop_back();
  return perm;
}

std::vector<uint32_t> ResultMerger::PixelsOfTask(const TaskSpec& task, int width, int height) {
  const PixelSubset& s = task.pixels;
  if (s.kind != PixelSubset::Kind::kPermutationStride) return PixelsOf(s, width, height);
  const uint64_t n = uint64_t(width) * uint64_t(height);
  if (s.stride == 0 || s.offset >= n)
    throw InputError("pixels.permutation_stride: offset/stride out of range");
  const auto perm = Permutation(s.permutation_seed, width, height);
  std::vector<uint32_t> px;
  px.reserve(CountPixels(s, width, height));
  for (uint64_t i = s.offset; i < n; i += s.stride) px.push_back((*perm)[i]);
  return px;
}

CheckedResult ResultMerger::Check(const TaskSpec& task, int width, int height,
                                  std::span<const float> rgb_sums) {
  CheckedResult out;
  out.problem = Validate(task, width, height, rgb_sums);
  if (out.problem.empty()) out.valid = ValidResult(task, rgb_sums);
  return out;
}

void ResultMerger::Merge(const ValidResult& result, Accumulator& acc) {
  const TaskSpec& task = result.task();
  const std::vector<uint32_t> pixels = PixelsOfTask(task, acc.width(), acc.height());
  acc.AddValidated(task, pixels, result.rgb_sums(), task.sample_end - task.sample_begin);
}

}  // namespace pf::server
