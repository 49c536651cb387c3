#include "server/assembly/result_merger.h"

#include <openssl/evp.h>

#include "common/core/error.h"

namespace pf::server {

ResultCheck ResultMerger::Validate(const TaskSpec& task, int width, int height,
                                   std::span<const float> rgb_sums, double max_sample_radiance) {
  if (task.sample_end <= task.sample_begin)
    return {ResultCheck::Verdict::kInvalid, "task: empty sample range"};
  const uint64_t pixels = CountPixels(task.pixels, width, height);
  return Accumulator::ValidateTaskResult(rgb_sums, pixels, task.sample_end - task.sample_begin,
                                         max_sample_radiance);
}

std::string ResultMerger::Digest(std::span<const float> rgb_sums) {
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  if (EVP_Digest(rgb_sums.data(), rgb_sums.size_bytes(), md, &len, EVP_sha256(), nullptr) != 1)
    throw SystemError("EVP_Digest(sha256) failed");
  return std::string(reinterpret_cast<const char*>(md), len);
}

std::shared_ptr<const std::vector<uint32_t>> ResultMerger::Permutation(uint64_t seed, int width, int height) {
  {
    std::lock_guard lock(cache_mu_);
    for (auto it = cache_.begin(); it != cache_.end(); ++it) {
      if (it->seed == seed && it->width == width && it->height == height) {
        cache_.splice(cache_.begin(), cache_, it);
        return cache_.front().perm;
      }
    }
  }
  // Built (O(pixels)) outside the cache's lock; two threads may build the same one at once.
  auto perm = std::make_shared<const std::vector<uint32_t>>(
      PixelPermutation(seed, uint32_t(width) * uint32_t(height)));
  std::lock_guard lock(cache_mu_);
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
                                  std::span<const float> rgb_sums, double max_sample_radiance) {
  CheckedResult out;
  const ResultCheck check = Validate(task, width, height, rgb_sums, max_sample_radiance);
  out.verdict = check.verdict;
  out.problem = check.reason;
  if (check.ok()) out.valid = ValidResult(task, rgb_sums);
  return out;
}

void ResultMerger::Merge(const ValidResult& result, Accumulator& acc) {
  const std::vector<uint32_t> pixels = PixelsOfTask(result.task(), acc.width(), acc.height());
  Merge(result, pixels, acc);
}

void ResultMerger::Merge(const ValidResult& result, std::span<const uint32_t> pixels, Accumulator& acc) {
  const TaskSpec& task = result.task();
  acc.AddValidated(task, pixels, result.rgb_sums(), task.sample_end - task.sample_begin);
}

}  // namespace pf::server
