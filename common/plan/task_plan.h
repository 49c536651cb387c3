#pragma once
// Job → tasks: the pure, deterministic expansion of a render job into independent
// *photon map × pixel subset × sample range* tasks (Wald 1999, §4.4; docs/design.md, §1 Jobs, tasks,
// results). The coordinator and the single-process renderer call the same functions, and a
// worker recomputes a task's pixels from its PixelSubset, so no pixel list ever travels.
//
// Plans:
//  (a) kMultipleMaps: s independent maps over the whole image (cut into tiles); every map
//      renders samples [0, spp) of every pixel; the pixel's value is the mean over maps.
//  (b) kMapsInTurn: pixel sample i uses map i: task (map i, tile) renders sample [i, i+1).
//  (c) kSkipping: per round a seeded permutation σ of all pixels; S² tasks per round, task
//      `start` with its own new map and the pixels σ[start], σ[start+S²], … (§4.4).
//  (d) kHierarchical: multilevel sampling over scanlines (1-D) or the image plane (2-D) with a
//      different map for each sample of a pixel (§4.5; common/plan/hierarchical.h). ExpandPlan
//      gives its static tasks (every level's detail tasks); the localization tasks follow from
//      the merged results (HierarchicalTasks).
//  (e) kProgressive: progressive photon mapping in Knaus & Zwicker's form (2011): pass p is the
//      multiple-maps plan's map p — its own map over the whole image in tiles, samples [0, spp) —
//      whose estimates sum every photon within the pass's radius r_p (render/progressive_radius.h)
//      instead of the k nearest. The image is the plain mean over passes, the multiple-maps merge.
//
// Seeds: map m of a job has map seed HashKey(job_seed, "map", m) and its pixel samples draw
// from streams keyed by HashKey(job_seed, "pix", m): samples of different maps are independent.

#include <cstdint>
#include <string>
#include <vector>

#include "common/render/radiance_part.h"

namespace pf {

enum class PlanKind { kMultipleMaps, kMapsInTurn, kSkipping, kHierarchical, kProgressive };

// What the hierarchical plan's levels render (common/plan/hierarchical.h, "Parts"): the whole
// radiance, or only its photon-map part, with emission and direct light rendered per pixel by
// tasks of their own (direct_samples per pixel) and added at assembly.
enum class HierarchyPart { kAll, kIndirect };

struct PlanSpec {
  PlanKind kind = PlanKind::kMultipleMaps;
  uint32_t maps = 1;               // kMultipleMaps: s; kProgressive: the passes
  uint32_t samples_per_pixel = 1;  // per map (a), total (b), per task and pixel (c), per map and pixel (d)
  uint32_t tile_size = 0;          // (a), (b): 0 = one tile = whole image; (d): rows per task, 0 = all
  // (a): the last row of tiles of the last map in tiles of this side (0 = like the others), so
  // that a farm's workers run out of work together: the tail where one worker renders the last
  // big tile while the others idle shrinks to a small one. A multiple of kPixelBlockSide (16)
  // that divides tile_size, so the image is bit-identical to the plan without it (docs/farm.md,
  // "Tail tiles").
  uint32_t tail_tile_size = 0;
  uint32_t stride = 1;  // (c): S
  uint32_t rounds = 1;  // (c)
  // (d) hierarchical (schedule and localization rule: common/plan/hierarchical.h)
  uint32_t levels = 4;              // L: level-0 points every 2^L pixels
  uint32_t dims = 1;                // 1 = scanlines, 2 = image plane
  uint32_t base_samples = 8;        // n0: maps (samples) of a level-0 point
  uint32_t min_samples = 1;         // n_l never falls below this
  double decay = 2;                 // n_l = max(min_samples, ceil(n0 / decay^l))
  double localize_threshold = 4;    // τ: |detail| > τ · level noise …
  double localize_contrast = 0.25;  // κ: … and > κ · |interpolation| ⇒ resample directly
  HierarchyPart hierarchy_part = HierarchyPart::kAll;
  uint32_t direct_samples = 0;  // kIndirect: samples per pixel of the emission + direct light pass (≥ 1)
};

struct PixelSubset {
  enum class Kind { kTile, kPermutationStride, kHierarchyLevel, kList } kind = Kind::kTile;
  // kTile: x ∈ [x0, x1), y ∈ [y0, y1), row-major.
  uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  // kPermutationStride: σ[offset], σ[offset + stride], … of PixelPermutation(seed, W·H).
  uint64_t permutation_seed = 0;
  uint32_t offset = 0, stride = 1;
  // kHierarchyLevel: the points of `level` (of a hierarchy with `levels`, `dims`) whose row is in
  // [y0, y1), together with their parents, ascending (common/plan/hierarchical.h).
  uint32_t level = 0, levels = 0, dims = 1;
  // kList: these pixel indices, ascending (localization: chosen from merged results).
  std::vector<uint32_t> list;
};

struct TaskSpec {
  uint64_t task_id = 0;  // index in the expansion: stable and unique within the job
  uint32_t round = 0;    // skipping round; hierarchical: the level (0 for other plans)
  uint64_t map_index = 0;
  uint64_t map_seed = 0;
  uint64_t pixel_seed = 0;
  PixelSubset pixels;
  uint32_t sample_begin = 0, sample_end = 1;
  // Which part of the radiance the task renders (radiance_part.h): kAll except in a hierarchical
  // plan with HierarchyPart::kIndirect (its levels and localization: kMapped; its per-pixel
  // emission + direct light tasks: kUnmapped).
  RadiancePart part = RadiancePart::kAll;
  // A progressive plan's pass (map_index = the pass): estimates sum the photons within the
  // pass's radius (render/progressive_radius.h) rather than the k nearest.
  bool progressive = false;
  // An animation's frame (frame_tasks.h): the index of the frame among the job's frames, whose
  // camera renders the task; `pixels` are then rows of the stacked image of all frames. 0 otherwise.
  uint32_t frame = 0;
};

// Throws InputError naming the field ("plan.skipping.stride: must be ≥ 1") for invalid plans.
void ValidatePlan(const PlanSpec& plan, int width, int height);
uint64_t CountTasks(const PlanSpec& plan, int width, int height);
uint32_t CountRounds(const PlanSpec& plan);  // 1 unless skipping
std::vector<TaskSpec> ExpandPlan(const PlanSpec& plan, int width, int height, uint64_t job_seed);

// The version of `plan`'s expansion into tasks (task ids and what each task renders, including
// the tasks a dynamic plan creates from results). A coordinator stores it with every job
// (JobSpec.plan.expansion_version) and, after a restart, resumes a job's merged results only if
// its own version is the same: a checkpoint lists task *ids*, which mean other tasks under
// another expansion. Bump a plan's number whenever its expansion changes.
//   static plans (a)-(c): 0, unchanged since the first release; multiple maps with tail tiles
//   (PlanSpec::tail_tile_size): 1 — a job without them expands and is versioned as before, and
//   a coordinator that predates the field (it would expand whole tiles under the same ids) sets
//   such a job's checkpoint aside instead of taking a tail tile's id for a whole tile;
//   hierarchical: 3 (1: localization tasks per level; 2: one batch per level-0 map and row band
//   once all levels are complete, docs/renderer.md "Localization"; 3: a detail task's pixels
//   share one random-number stream, renderer.h PixelStreams — same ids, other pixel values);
//   4 with HierarchyPart::kIndirect (emission + direct light tasks first, the levels render the
//   map part only: other ids and values; kAll keeps 3, its tasks are unchanged);
//   progressive: 0 (new).
uint32_t PlanExpansionVersion(const PlanSpec& plan);

uint64_t MapSeed(uint64_t job_seed, uint64_t map_index);
uint64_t PixelSeed(uint64_t job_seed, uint64_t map_index);

// A uniformly random permutation of [0, n) from a seed (Fisher–Yates with the project RNG).
std::vector<uint32_t> PixelPermutation(uint64_t seed, uint32_t n);
// The pixel indices (y·W + x) of a subset, in subset order.
std::vector<uint32_t> PixelsOf(const PixelSubset& subset, int width, int height);
// Number of pixels without materialising them.
uint64_t CountPixels(const PixelSubset& subset, int width, int height);

std::string DescribePlan(const PlanSpec& plan);

// The plan as the EXR header's `plan` records it (docs/farm.md, "Image headers"): its name, then
// " flag=value" for each parameter that shapes the image, named and ordered as pf render's flags,
// e.g. "multiple-maps maps=4 spp=2 tile=64". Real values as RealText (common/core/real_text.h).
// A stable format: text compared across pf versions and between pf render and the farm. The tail
// tile is left out: it only schedules the last tiles, the image is the same without it.
std::string PlanRecordText(const PlanSpec& plan);

}  // namespace pf
