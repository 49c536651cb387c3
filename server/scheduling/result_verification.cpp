#include "server/scheduling/result_verification.h"

#include <algorithm>
#include <cmath>

#include "common/core/rng.h"
#include "server/jobs/random_id.h"

namespace pf::server {

namespace {

// Robust scale of a normal sample from its median absolute deviation.
constexpr double kMadToSigma = 1.4826;

double MedianOf(std::vector<double> v) {
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(mid), v.end());
  const double upper = v[mid];
  if (v.size() % 2) return upper;
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + std::ptrdiff_t(mid)));
}

}  // namespace

uint64_t ResultGroup(const TaskSpec& task) {
  const PixelSubset& p = task.pixels;
  uint64_t h = HashKey(uint64_t(p.kind), uint64_t(task.part));
  switch (p.kind) {
    case PixelSubset::Kind::kTile:
      return HashKey(h, HashKey(p.x0, p.y0), HashKey(p.x1, p.y1));
    case PixelSubset::Kind::kPermutationStride:
      // Every task of a skipping job is a uniformly random subset of the pixels of the same size:
      // all of them are one group (the permutation and offset are left out on purpose).
      return HashKey(h, p.stride);
    case PixelSubset::Kind::kHierarchyLevel:
      return HashKey(HashKey(h, p.level, HashKey(p.levels, p.dims)), p.y0, p.y1);
    case PixelSubset::Kind::kList:
      return kUntestedGroup;  // a localization task's own pixels: no other result has them
  }
  return h;
}

ResultSummary SummarizeResult(const TaskSpec& task, std::span<const float> rgb_sums) {
  ResultSummary s;
  s.group = ResultGroup(task);
  const double samples =
      double(task.sample_end > task.sample_begin ? task.sample_end - task.sample_begin : 1);
  double sum = 0;
  for (const float v : rgb_sums) sum += double(v);
  s.mean = rgb_sums.empty() ? 0.0 : sum / (double(rgb_sums.size()) * samples);
  std::vector<double> pixels(rgb_sums.size() / 3);
  for (size_t i = 0; i < pixels.size(); ++i)
    pixels[i] =
        (double(rgb_sums[3 * i]) + double(rgb_sums[3 * i + 1]) + double(rgb_sums[3 * i + 2])) / samples;
  if (pixels.empty()) return s;
  std::sort(pixels.begin(), pixels.end());
  const size_t n = pixels.size();
  s.median = n % 2 ? pixels[n / 2] : 0.5 * (pixels[n / 2 - 1] + pixels[n / 2]);
  const size_t lo = n / 4, hi = n - n / 4;
  double mid = 0;
  for (size_t i = lo; i < hi; ++i) mid += pixels[i];
  s.midmean = mid / double(hi - lo);
  return s;
}

OutlierScore ScoreAgainst(double mean, std::span<const double> others, double threshold) {
  OutlierScore score;
  if (others.size() < kOutlierMinReferences) return score;
  score.tested = true;
  const std::vector<double> values(others.begin(), others.end());
  const double median = MedianOf(values);
  std::vector<double> deviations;
  deviations.reserve(values.size());
  for (const double v : values) deviations.push_back(std::abs(v - median));
  const double mad = MedianOf(std::move(deviations));
  // The relative floor: results of a quiet group (many samples, a flat region) agree closely, and
  // an honest result a little off would otherwise be many "deviations" away. The absolute floor
  // keeps a group of black results from dividing by zero (an honest black result is 0 too).
  const double scale = std::max({kMadToSigma * mad, kOutlierRelativeFloor * std::abs(median), 1e-30});
  score.z = std::abs(mean - median) / scale;
  score.outlier = score.z > threshold;
  return score;
}

ResultVerification::ResultVerification(VerificationOptions options)
    : options_(options), uniform_([] { return RandomUnit(); }) {}

bool ResultVerification::ChooseAtRandom() {
  if (!(options_.fraction > 0)) return false;
  if (options_.fraction >= 1) return true;
  return uniform_() < options_.fraction;
}

std::vector<double> ResultVerification::References(const Job& job, uint64_t group) const {
  if (group == kUntestedGroup) return {};
  auto it = jobs_.find(&job);
  if (it == jobs_.end()) return {};
  auto g = it->second.references.find(group);
  return g == it->second.references.end() ? std::vector<double>{} : g->second;
}

void ResultVerification::RecordMean(const Job& job, uint64_t group, double mean) {
  if (group == kUntestedGroup) return;
  std::vector<double>& refs = jobs_[&job].references[group];
  if (refs.size() >= kOutlierReferences) refs.erase(refs.begin());
  refs.push_back(mean);
}

ResultVerification::Verification& ResultVerification::Add(Job& job, uint64_t task_id, std::string worker,
                                                          std::string digest, std::string reason) {
  auto v = std::make_unique<Verification>();
  v->id = next_id_++;
  v->job = &job;
  v->task_id = task_id;
  v->reason = std::move(reason);
  v->digests.emplace_back(std::move(worker), std::move(digest));
  Verification& ref = *v;
  all_[ref.id] = std::move(v);
  ++queued_;
  ++jobs_[&job].pending;
  return ref;
}

ResultVerification::Verification* ResultVerification::Find(uint64_t id) {
  auto it = all_.find(id);
  return it == all_.end() ? nullptr : it->second.get();
}

ResultVerification::Verification* ResultVerification::FindLease(const std::string& lease_id) {
  auto it = by_lease_.find(lease_id);
  return it == by_lease_.end() ? nullptr : Find(it->second);
}

ResultVerification::Verification* ResultVerification::NextQueued(
    const std::function<bool(const Verification&)>& may_take) {
  if (queued_ == 0) return nullptr;
  for (auto& [id, v] : all_)
    if (v->state == Verification::State::kQueued && may_take(*v)) return v.get();
  return nullptr;
}

void ResultVerification::Leased(Verification& v, std::string lease_id, std::string worker, double deadline) {
  if (v.state == Verification::State::kQueued) --queued_;
  v.state = Verification::State::kLeased;
  v.lease_id = std::move(lease_id);
  v.verifier = std::move(worker);
  v.deadline = deadline;
  ++v.leases;
  by_lease_[v.lease_id] = v.id;
}

void ResultVerification::Unindex(Verification& v) {
  if (v.state == Verification::State::kQueued) --queued_;
  if (!v.lease_id.empty()) by_lease_.erase(v.lease_id);
  v.lease_id.clear();
  v.checking = false;
}

void ResultVerification::Requeue(Verification& v) {
  Unindex(v);
  v.verifier.clear();
  v.state = Verification::State::kQueued;
  ++queued_;
}

void ResultVerification::ToReferee(Verification& v) {
  Unindex(v);
  v.state = Verification::State::kRefereeing;
}

void ResultVerification::Remove(uint64_t id) {
  auto it = all_.find(id);
  if (it == all_.end()) return;
  Verification& v = *it->second;
  Unindex(v);
  if (!v.detached)
    if (auto j = jobs_.find(v.job); j != jobs_.end() && j->second.pending > 0) --j->second.pending;
  all_.erase(it);
}

std::vector<uint64_t> ResultVerification::Expired(double now) const {
  std::vector<uint64_t> out;
  for (const auto& [id, v] : all_)
    if (v->state == Verification::State::kLeased && !v->checking && now >= v->deadline) out.push_back(id);
  return out;
}

std::vector<ResultVerification::Verification*> ResultVerification::QueuedOf(const Job& job) {
  std::vector<Verification*> out;
  if (Pending(job) == 0) return out;
  for (auto& [id, v] : all_)
    if (v->job == &job && !v->detached && v->state == Verification::State::kQueued) out.push_back(v.get());
  return out;
}

std::vector<ResultVerification::Verification*> ResultVerification::LeasedTo(const Job& job,
                                                                            const std::string& worker) {
  std::vector<Verification*> out;
  if (Pending(job) == 0) return out;
  for (auto& [id, v] : all_)
    if (v->job == &job && v->state == Verification::State::kLeased && v->verifier == worker && !v->checking)
      out.push_back(v.get());
  return out;
}

uint64_t ResultVerification::Pending(const Job& job) const {
  auto it = jobs_.find(&job);
  return it == jobs_.end() ? 0 : it->second.pending;
}

uint64_t ResultVerification::Verified(const Job& job) const {
  auto it = jobs_.find(&job);
  return it == jobs_.end() ? 0 : it->second.verified;
}

void ResultVerification::CountVerified(const Job& job) {
  ++jobs_[&job].verified;
}

bool ResultVerification::Names(const Job& job) const {
  for (const auto& [id, v] : all_)
    if (v->job == &job) return true;
  return false;
}

void ResultVerification::DropJob(const Job& job, bool ended) {
  for (auto it = all_.begin(); it != all_.end();) {
    Verification& v = *it->second;
    if (v.job != &job || v.detached) {
      ++it;
      continue;
    }
    if (v.state == Verification::State::kRefereeing) {
      v.detached = true;  // its verdict still convicts (Scheduler::RefereeVerdict)
      ++it;
      continue;
    }
    Unindex(v);
    it = all_.erase(it);
  }
  auto j = jobs_.find(&job);
  if (j == jobs_.end()) return;
  // A finished job keeps its counts (its status shows them) and its convictions, not its references.
  std::unordered_map<uint64_t, std::vector<double>>().swap(j->second.references);
  j->second.pending = 0;
  if (!ended) j->second.verified = 0;
}

}  // namespace pf::server
