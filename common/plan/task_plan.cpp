#include "common/plan/task_plan.h"

#include <numeric>

#include "common/core/error.h"
#include "common/core/rng.h"
#include "common/plan/hierarchical.h"
#include "common/plan/plan_factory.h"
#include "common/render/renderer.h"

namespace pf {
namespace {

constexpr uint64_t kMapTag = 0x6d6170;     // "map"
constexpr uint64_t kPixTag = 0x706978;     // "pix"
constexpr uint64_t kPermTag = 0x7065726d;  // "perm"

std::vector<PixelSubset> Tiles(uint32_t tile_size, int width, int height) {
  std::vector<PixelSubset> tiles;
  const uint32_t tw = tile_size == 0 ? uint32_t(width) : tile_size;
  const uint32_t th = tile_size == 0 ? uint32_t(height) : tile_size;
  for (uint32_t y = 0; y < uint32_t(height); y += th)
    for (uint32_t x = 0; x < uint32_t(width); x += tw) {
      PixelSubset t;
      t.kind = PixelSubset::Kind::kTile;
      t.x0 = x;
      t.y0 = y;
      t.x1 = std::min<uint32_t>(x + tw, uint32_t(width));
      t.y1 = std::min<uint32_t>(y + th, uint32_t(height));
      tiles.push_back(t);
    }
  return tiles;
}

uint64_t NumTiles(uint32_t tile_size, int width, int height) {
  if (tile_size == 0) return 1;
  return uint64_t((width + tile_size - 1) / tile_size) * ((height + tile_size - 1) / tile_size);
}

// The tiles of the multiple-maps plan's last map: the same tiles, except the last row of them,
// each cut into tail×tail tiles (clipped at the image border) in row-major order within it. The
// pixels and their order of rendering within a pixel block are those of the uncut tiles: tail is
// a multiple of kPixelBlockSide, so every 16×16 block (renderer.h, PixelBlockState) stays whole.
std::vector<PixelSubset> TilesWithTail(uint32_t tile_size, uint32_t tail, int width, int height) {
  std::vector<PixelSubset> tiles = Tiles(tile_size, width, height);
  if (tail == 0 || tile_size == 0) return tiles;
  const uint32_t last_row_y0 = tiles.back().y0;
  std::vector<PixelSubset> out;
  out.reserve(tiles.size());
  for (const PixelSubset& t : tiles) {
    if (t.y0 != last_row_y0) {
      out.push_back(t);
      continue;
    }
    for (uint32_t y = t.y0; y < t.y1; y += tail)
      for (uint32_t x = t.x0; x < t.x1; x += tail) {
        PixelSubset s = t;
        s.x0 = x;
        s.y0 = y;
        s.x1 = std::min(x + tail, t.x1);
        s.y1 = std::min(y + tail, t.y1);
        out.push_back(s);
      }
  }
  return out;
}

uint64_t NumTailTiles(uint32_t tile_size, uint32_t tail, int width, int height) {
  if (tail == 0 || tile_size == 0) return NumTiles(tile_size, width, height);
  const uint64_t cols = (uint64_t(width) + tile_size - 1) / tile_size;
  const uint64_t rows = (uint64_t(height) + tile_size - 1) / tile_size;
  const uint64_t last_h = uint64_t(height) - (rows - 1) * tile_size;
  uint64_t cut = 0;  // tail tiles in the last row of tiles
  for (uint64_t c = 0; c < cols; ++c) {
    const uint64_t w = std::min<uint64_t>(tile_size, uint64_t(width) - c * tile_size);
    cut += ((w + tail - 1) / tail) * ((last_h + tail - 1) / tail);
  }
  return (rows - 1) * cols + cut;
}

}  // namespace

uint64_t MapSeed(uint64_t job_seed, uint64_t map_index) {
  return HashKey(job_seed, kMapTag, map_index);
}
uint64_t PixelSeed(uint64_t job_seed, uint64_t map_index) {
  return HashKey(job_seed, kPixTag, map_index);
}

void ValidatePlan(const PlanSpec& plan, int width, int height) {
  if (width <= 0 || height <= 0) throw InputError("camera: width and height must be positive");
  if (plan.tail_tile_size != 0 && plan.kind != PlanKind::kMultipleMaps)
    throw InputError("plan: tail tiles (tail_tile_size) are a multiple-maps option");
  Plans().FindKind(plan.kind).validate(plan, width, height);
}

uint64_t CountTasks(const PlanSpec& plan, int width, int height) {
  switch (plan.kind) {
    case PlanKind::kProgressive:
    case PlanKind::kMultipleMaps:
      return uint64_t(plan.maps - 1) * NumTiles(plan.tile_size, width, height) +
             NumTailTiles(plan.tile_size, plan.tail_tile_size, width, height);
    case PlanKind::kMapsInTurn:
      return uint64_t(plan.samples_per_pixel) * NumTiles(plan.tile_size, width, height);
    case PlanKind::kSkipping:
      return uint64_t(plan.rounds) * plan.stride * plan.stride;
    case PlanKind::kHierarchical:
      return CountHierarchicalStaticTasks(plan, width, height);
  }
  return 0;
}

uint32_t CountRounds(const PlanSpec& plan) {
  return plan.kind == PlanKind::kSkipping ? plan.rounds : 1;
}

uint32_t PlanExpansionVersion(const PlanSpec& plan) {
  if (plan.kind == PlanKind::kHierarchical) return plan.hierarchy_part == HierarchyPart::kIndirect ? 4 : 3;
  return plan.kind == PlanKind::kMultipleMaps && plan.tail_tile_size != 0 ? 1 : 0;
}

std::vector<TaskSpec> ExpandPlan(const PlanSpec& plan, int width, int height, uint64_t job_seed) {
  ValidatePlan(plan, width, height);
  if (plan.kind == PlanKind::kHierarchical) return HierarchicalStaticTasks(plan, width, height, job_seed);
  std::vector<TaskSpec> tasks;
  tasks.reserve(CountTasks(plan, width, height));
  auto add = [&](uint32_t round, uint64_t map, const PixelSubset& px, uint32_t s0, uint32_t s1) {
    TaskSpec t;
    t.task_id = tasks.size();
    t.round = round;
    t.map_index = map;
    t.map_seed = MapSeed(job_seed, map);
    t.pixel_seed = PixelSeed(job_seed, map);
    t.pixels = px;
    t.sample_begin = s0;
    t.sample_end = s1;
    tasks.push_back(t);
  };
  switch (plan.kind) {
    case PlanKind::kProgressive:
    case PlanKind::kMultipleMaps: {
      const auto tiles = Tiles(plan.tile_size, width, height);
      // Map-major order: the tiles of one map are adjacent, so a worker that has built map m
      // tends to lease its other tiles next (map affinity). The last map ends in tail tiles
      // (PlanSpec::tail_tile_size): tasks are leased in id order (map affinity aside, docs/farm.md),
      // so those are the last ones.
      for (uint32_t m = 0; m + 1 < plan.maps; ++m)
        for (const PixelSubset& t : tiles) add(0, m, t, 0, plan.samples_per_pixel);
      for (const PixelSubset& t : TilesWithTail(plan.tile_size, plan.tail_tile_size, width, height))
        add(0, plan.maps - 1, t, 0, plan.samples_per_pixel);
      break;
    }
    case PlanKind::kMapsInTurn: {
      const auto tiles = Tiles(plan.tile_size, width, height);
      for (uint32_t i = 0; i < plan.samples_per_pixel; ++i)
        for (const PixelSubset& t : tiles) add(0, i, t, i, i + 1);
      break;
    }
    case PlanKind::kSkipping: {
      const uint32_t s2 = plan.stride * plan.stride;
      for (uint32_t r = 0; r < plan.rounds; ++r) {
        PixelSubset px;
        px.kind = PixelSubset::Kind::kPermutationStride;
        px.permutation_seed = HashKey(job_seed, kPermTag, r);
        px.stride = s2;
        for (uint32_t start = 0; start < s2; ++start) {
          px.offset = start;
          add(r, uint64_t(r) * s2 + start, px, 0, plan.samples_per_pixel);
        }
      }
      break;
    }
    case PlanKind::kHierarchical:
      break;  // above
  }
  // A progressive pass is a multiple-maps map whose estimates read the pass's radius.
  if (plan.kind == PlanKind::kProgressive)
    for (TaskSpec& t : tasks) t.progressive = true;
  return tasks;
}

std::vector<uint32_t> PixelPermutation(uint64_t seed, uint32_t n) {
  std::vector<uint32_t> perm(n);
  std::iota(perm.begin(), perm.end(), 0u);
  Rng rng = Rng::ForKey(seed);
  for (uint32_t i = n; i > 1; --i) std::swap(perm[i - 1], perm[rng.UniformInt(i)]);
  return perm;
}

uint64_t CountPixels(const PixelSubset& s, int width, int height) {
  if (s.kind == PixelSubset::Kind::kList) return s.list.size();
  if (s.kind == PixelSubset::Kind::kHierarchyLevel) return PixelsOf(s, width, height).size();
  if (s.kind == PixelSubset::Kind::kTile)
    return s.x1 > s.x0 && s.y1 > s.y0 ? uint64_t(s.x1 - s.x0) * (s.y1 - s.y0) : 0;
  const uint64_t n = uint64_t(width) * uint64_t(height);
  return s.offset < n && s.stride > 0 ? (n - s.offset + s.stride - 1) / s.stride : 0;
}

std::vector<uint32_t> PixelsOf(const PixelSubset& s, int width, int height) {
  std::vector<uint32_t> px;
  if (s.kind == PixelSubset::Kind::kTile) {
    if (s.x1 > uint32_t(width) || s.y1 > uint32_t(height) || s.x0 >= s.x1 || s.y0 >= s.y1)
      throw InputError("pixels.tile: outside the image or empty");
    px.reserve(CountPixels(s, width, height));
    for (uint32_t y = s.y0; y < s.y1; ++y)
      for (uint32_t x = s.x0; x < s.x1; ++x) px.push_back(y * uint32_t(width) + x);
    return px;
  }
  if (s.kind == PixelSubset::Kind::kHierarchyLevel) {
    if (s.levels < 1 || s.levels > 16 || (s.dims != 1 && s.dims != 2) || s.level > s.levels || s.y0 >= s.y1 ||
        s.y1 > uint32_t(height))
      throw InputError("pixels.hierarchy_level: level, dims or rows out of range");
    return Hierarchy(width, height, s.levels, s.dims).TaskPixels(s.level, s.y0, s.y1);
  }
  if (s.kind == PixelSubset::Kind::kList) {
    const uint64_t n = uint64_t(width) * uint64_t(height);
    for (size_t i = 0; i < s.list.size(); ++i)
      if (s.list[i] >= n || (i > 0 && s.list[i] <= s.list[i - 1]))
        throw InputError("pixels.list: indices must be ascending and inside the image");
    return s.list;
  }
  const uint32_t n = uint32_t(width) * uint32_t(height);
  if (s.stride == 0 || s.offset >= n)
    throw InputError("pixels.permutation_stride: offset/stride out of range");
  const std::vector<uint32_t> perm = PixelPermutation(s.permutation_seed, n);
  px.reserve(CountPixels(s, width, height));
  for (uint64_t i = s.offset; i < n; i += s.stride) px.push_back(perm[i]);
  return px;
}

std::string DescribePlan(const PlanSpec& p) {
  return Plans().FindKind(p.kind).describe(p);
}

std::string PlanRecordText(const PlanSpec& p) {
  const PlanEntry& entry = Plans().FindKind(p.kind);
  return std::string(entry.name) + entry.record(p);
}

}  // namespace pf
