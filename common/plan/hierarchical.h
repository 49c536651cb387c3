#pragma once
// The hierarchical photon map (Wald 1999, §4.5; Heinrich's multilevel integro-approximation after
// Keller) as a plan of independent tasks (docs/renderer.md, "Hierarchical plan").
//
// Structure. Along an axis of n pixels, the level-0 points are every 2^L-th pixel and the last
// one; each interval [a, b] between two points with b − a ≥ 2 is bisected at m = ⌊(a+b)/2⌋, and
// m belongs to the next level, with parents a and b (weights 1 − t, t for t = (m−a)/(b−a); ½ on
// the power-of-two segments of 2^L + 1 pixels the thesis uses). Levels run 0..L.
//  1-D (dims = 1): every scanline on its own: pixel (x, y) has x's level and parents (a, y), (b, y).
//  2-D (dims = 2): pixel (x, y) has level max(lx, ly); if lx > ly its parents are (ax, y), (bx, y);
//      if ly > lx (x, ay), (x, by); if both are equal, the four corners, bilinearly weighted.
//      Parents always belong to lower levels.
//
// Schedule. Level l gets n_l = max(min_samples, ⌈n0 / decay^l⌉) samples (n0 = base_samples),
// sample j of level l from map M_l + j with M_l = Σ_{k<l} n_k, so every sample of a pixel comes
// from a different map and Nmax = Σ_l n_l maps are used in all (HierarchyStats reports Nmax,
// navg = mean samples per pixel, and the evaluations per pixel, which also count the parents'
// evaluations that the details need).
//
// Details. A level-0 point is the mean of its n0 direct samples. A level-l point p is
//     F(p) = Σ_q w_q F(q) + mean_j d_j(p),   d_j(p) = f_j(p) − Σ_q w_q f_j(q),
// where f_j is the image rendered with map j: the detail uses the *same* map at p and its
// parents, so where the image is smooth (and the photon map's low-frequency error is smooth)
// d_j is small and has small variance, and F(p) inherits the many maps of the coarse points.
// A detail task (map j, level l, row band) renders the band's level-l points and their parents
// with map j and with one shared random-number stream (PixelStreams::kShared, renderer.h; the
// task executor decides it): the same map cancels the map's error in d_j, the same random numbers
// cancel the Monte Carlo noise of direct light and sub-pixel position, which would otherwise add
// three times. The assembly turns the task's sums into details.
//
// Localization. Once all detail tasks of level l are merged, let D(p) be p's mean detail and
// I(p) the mean interpolation Σ w f_j(q) (luminance), and σ_l the level's noise: the median over
// the level's points of the standard error of D(p) (from the spread of its n_l ≥ 2 per-map
// details; the median, because the few points at a discontinuity have a large spread too), or,
// with n_l = 1, 1.4826 · median |D − median D| (robust to the few discontinuity points, as long
// as they are few). p is localized if |D(p)| > τ·σ_l and |D(p)| > κ·|I(p)| (τ = localize_threshold,
// κ = localize_contrast): the detail is both far outside the level's noise and visible. A
// localized pixel discards the interpolation: it is resampled directly with n0 samples from maps
// 0..n0−1 (the level-0 maps, never used at that pixel before), and F(p) is their mean. Both
// quantities are computed from the fixed-point sums, so the decision is the same for any merge
// order, and the localization tasks (ids after the static tasks; created once every level is
// complete, one per level-0 map and band for the localized points of all levels, so each of those
// maps is built once more, not once per level) are a pure function of the plan and the merged
// results (HierarchicalTasks).
//
// Parts (HierarchyPart, task_plan.h). With kAll every task renders the whole radiance. With
// kIndirect the levels and localization render only the photon-map part (RadiancePart::kMapped:
// global and caustic estimates, local pass), and emission + direct light (kUnmapped) is rendered
// per pixel with direct_samples independent samples by tasks of its own (one per row band, ids
// before the levels'), added to the hierarchy's value at assembly. Why: the hierarchy cures the
// photon map's low-frequency error (details with the same map cancel it); direct light (§4.2.1:
// Monte Carlo shadow rays) and the sub-pixel position are white noise, which a detail adds up to
// (1 + Σ w²)/n_l times wherever common random numbers do not cancel it (shadow edges, glossy
// highlights), and a direct-light edge is a visible detail that localization resamples with n0
// full samples; the map part is smooth across shadow edges.
//
// Assembly. Direct sums, detail sums and interpolation sums (and with kIndirect the per-pixel
// emission + direct light sums) are kept in 64-bit fixed point (2^-32), so merging is exact,
// order-independent, and idempotent per task (a task id merged twice is ignored). Resolve
// evaluates F level by level and adds the per-pixel part.

#include <array>
#include <cstdint>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "common/core/byte_codec.h"
#include "common/image/image.h"
#include "common/plan/hierarchy.h"
#include "common/plan/task_plan.h"

namespace pf {

class HierarchicalAssembly {
 public:
  HierarchicalAssembly() = default;
  HierarchicalAssembly(const PlanSpec& plan, int width, int height);

  // Merges one task's result: rgb_sums has 3 floats per pixel of `pixels` (the task's subset,
  // PixelsOf order), each the sum over `samples` samples. Caller has validated the sizes. A task
  // id merged before is ignored (returns false).
  bool Add(const TaskSpec& task, std::span<const uint32_t> pixels, std::span<const float> rgb_sums,
           uint32_t samples);

  Image Resolve() const;
  // All detail tasks of `level` are merged (level 0: its direct tasks).
  bool LevelComplete(uint32_t level) const;
  // The localized points of a complete level ≥ 1 (see the header comment), ascending.
  std::vector<uint32_t> Localized(uint32_t level) const;
  // σ_l of a complete level ≥ 1.
  double LevelNoise(uint32_t level) const;
  uint64_t tasks_merged() const { return merged_.size(); }
  uint64_t samples_merged() const { return samples_merged_; }
  const Hierarchy& hierarchy() const { return hierarchy_; }

  // Checkpoints (inside Accumulator::Serialize): the state after the plan, which the reader
  // must construct the assembly with. DeserializeFrom throws InputError if the sizes disagree.
  void SerializeTo(std::string& out) const;
  void DeserializeFrom(ByteReader& in);

  bool operator==(const HierarchicalAssembly& o) const;

 private:
  PlanSpec plan_;
  Hierarchy hierarchy_{1, 1, 0, 1};
  std::vector<uint64_t> level_tasks_;         // detail (direct for level 0) tasks per level
  std::vector<uint64_t> level_tasks_merged_;  // … of which merged
  std::vector<int64_t> direct_;               // 3 per pixel, fixed point
  std::vector<uint32_t> direct_samples_;
  std::vector<int64_t> detail_;   // 3 per pixel: Σ_j d_j, fixed point
  std::vector<int64_t> interp_;   // per pixel: Σ_j luminance(Σ w f_j(q)), fixed point
  std::vector<int64_t> detail2_;  // per pixel: Σ_j luminance(d_j)², fixed point
  std::vector<uint32_t> detail_maps_;
  // HierarchyPart::kIndirect only (empty otherwise): emission + direct light sums per pixel.
  std::vector<int64_t> unmapped_;  // 3 per pixel, fixed point
  std::vector<uint32_t> unmapped_samples_;
  std::set<uint64_t> merged_;
  uint64_t samples_merged_ = 0;
  struct LevelDetail {
    std::vector<uint32_t> points;
    std::vector<double> d, interp;
    std::vector<double> standard_error;  // per point, if every point has ≥ 2 maps
  };
  LevelDetail DetailsOf(uint32_t level) const;
};

// Every task the plan has, given what is merged: the static tasks (ExpandPlan) and, once every
// level is complete, the localization tasks: per level-0 map j and row band, the band's localized
// points of all levels (round = levels + 1). Ids are the index in the result; a prefix of a later
// answer is always the earlier answer.
std::vector<TaskSpec> HierarchicalTasks(const PlanSpec& plan, int width, int height, uint64_t job_seed,
                                        const HierarchicalAssembly& merged);

// Progress and ETA (docs/farm.md, "ETA"). This plan's tasks differ in cost by orders of magnitude
// (a level-0 task renders a few points, a last-level task most of the image, a localization task a
// list of pixels), and its localization tasks exist only once every level is complete, so the
// coordinator counts *work*, not tasks. The work of a task is its pixel samples plus the cost of
// its photon map in pixel samples: kMapWorkPerPhoton per photon (measured: a 10k-photon map costs
// about what 1000-3000 pixel samples cost, Cornell box with Monte Carlo direct light; the ETA
// test checks the estimate with a map cost 2.5x off). 0 photons = no map (the path integrator).
inline constexpr double kMapWorkPerPhoton = 0.2;
uint64_t MapWork(uint64_t photons_per_map);
// The work of each task (in order).
std::vector<uint64_t> HierarchicalTaskWork(const PlanSpec& plan, int width, int height,
                                           uint64_t photons_per_map, std::span<const TaskSpec> tasks);
// The expected work of the localization tasks, before they exist (HierarchicalTasks creates them
// once every level is complete). Localized points of a complete level are known (Localized); those
// of level l not yet complete are extrapolated as A·g^l, g = 1.5 in 1-D and 3 in 2-D: a
// discontinuity meets 2^(dims−1) times more points at each finer level, and the counts measured on
// the Cornell box (129², levels 1..7) grow by 1.1-1.5× (1-D) and 2.3-3× (2-D) per level, so g is
// their upper end (an estimate that errs high is revised down, and the progress jumps forward
// rather than back); A is fitted to the complete levels' counts (Σ count / Σ g^l, at least 1/g),
// or, before level 1 is complete, as if every level-1 point were localized. Each level's estimate
// is capped at its number of points. `merged` may be null (nothing merged yet).
uint64_t ExpectedLocalizationWork(const PlanSpec& plan, int width, int height, uint64_t photons_per_map,
                                  const HierarchicalAssembly* merged);

// The static tasks (part of ExpandPlan).
std::vector<TaskSpec> HierarchicalStaticTasks(const PlanSpec& plan, int width, int height, uint64_t job_seed);
uint64_t CountHierarchicalStaticTasks(const PlanSpec& plan, int width, int height);

}  // namespace pf
