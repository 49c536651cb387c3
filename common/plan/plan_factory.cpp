#include "common/plan/plan_factory.h"

#include "common/core/error.h"
#include "common/plan/hierarchy.h"
#include "common/render/renderer.h"

namespace pf {
namespace {

void ValidateMultipleMaps(const PlanSpec& plan, int, int) {
  if (plan.maps < 1) throw InputError("plan.multiple_maps.maps: must be >= 1");
  if (plan.samples_per_pixel < 1) throw InputError("plan.multiple_maps.samples_per_pixel: must be >= 1");
  if (plan.tail_tile_size != 0 &&
      (plan.tile_size == 0 || plan.tail_tile_size >= plan.tile_size ||
       plan.tile_size % plan.tail_tile_size != 0 || plan.tail_tile_size % kPixelBlockSide != 0))
    throw InputError("plan.multiple_maps.tail_tile_size: " + std::to_string(plan.tail_tile_size) +
                     " must be 0 or a multiple of " + std::to_string(kPixelBlockSide) +
                     " smaller than tile_size (" + std::to_string(plan.tile_size) + ") that divides it");
}

void ValidateMapsInTurn(const PlanSpec& plan, int, int) {
  if (plan.samples_per_pixel < 1) throw InputError("plan.maps_in_turn.samples_per_pixel: must be >= 1");
}

void ValidateSkipping(const PlanSpec& plan, int width, int height) {
  if (plan.stride < 1) throw InputError("plan.skipping.stride: must be >= 1");
  if (uint64_t(plan.stride) * plan.stride > uint64_t(width) * uint64_t(height))
    throw InputError("plan.skipping.stride: S² = " + std::to_string(uint64_t(plan.stride) * plan.stride) +
                     " exceeds the number of pixels");
  if (plan.rounds < 1) throw InputError("plan.skipping.rounds: must be >= 1");
  if (plan.samples_per_pixel < 1) throw InputError("plan.skipping.samples_per_pixel: must be >= 1");
}

void ValidateProgressive(const PlanSpec& plan, int, int) {
  if (plan.maps < 1) throw InputError("plan.progressive.passes: must be >= 1");
  if (plan.samples_per_pixel < 1) throw InputError("plan.progressive.samples_per_pixel: must be >= 1");
}

std::string DescribeProgressive(const PlanSpec& p) {
  return "progressive (Knaus & Zwicker 2011): " + std::to_string(p.maps) + " passes x " +
         std::to_string(p.samples_per_pixel) + " spp, radius query, tile " + std::to_string(p.tile_size);
}

std::string DescribeMultipleMaps(const PlanSpec& p) {
  return "multiple maps: " + std::to_string(p.maps) + " maps x " + std::to_string(p.samples_per_pixel) +
         " spp, tile " + std::to_string(p.tile_size) +
         (p.tail_tile_size ? " (last row " + std::to_string(p.tail_tile_size) + ")" : "");
}

std::string DescribeMapsInTurn(const PlanSpec& p) {
  return "maps in turn: " + std::to_string(p.samples_per_pixel) + " maps/spp, tile " +
         std::to_string(p.tile_size);
}

std::string DescribeSkipping(const PlanSpec& p) {
  return "skipping: S=" + std::to_string(p.stride) + ", " + std::to_string(p.rounds) + " rounds, " +
         std::to_string(p.samples_per_pixel) + " spp per round";
}

std::string DescribeHierarchical(const PlanSpec& p) {
  const HierarchySchedule s = MakeHierarchySchedule(p);
  std::string n;
  for (uint32_t v : s.samples) {
    if (!n.empty()) n += ',';
    n += std::to_string(v);
  }
  return "hierarchical " + std::to_string(p.dims) + "-D: L=" + std::to_string(p.levels) + ", n_l=" + n +
         " (Nmax " + std::to_string(s.nmax) + "), localize tau=" + std::to_string(p.localize_threshold) +
         " kappa=" + std::to_string(p.localize_contrast) + ", rows per task " + std::to_string(p.tile_size) +
         (p.hierarchy_part == HierarchyPart::kIndirect
              ? ", photon-map part only (emission + direct light per pixel, " +
                    std::to_string(p.direct_samples) + " spp)"
              : "");
}

}  // namespace

const NamedRegistry<PlanEntry>& Plans() {
  using K = PlanKind;
  static const NamedRegistry<PlanEntry> registry(
      "plan", {{"multiple-maps", K::kMultipleMaps, ValidateMultipleMaps, DescribeMultipleMaps},
               {"maps-in-turn", K::kMapsInTurn, ValidateMapsInTurn, DescribeMapsInTurn},
               {"skipping", K::kSkipping, ValidateSkipping, DescribeSkipping},
               {"hierarchical", K::kHierarchical, ValidateHierarchicalPlan, DescribeHierarchical},
               {"progressive", K::kProgressive, ValidateProgressive, DescribeProgressive}});
  return registry;
}

PlanSpec MakePlan(std::string_view name, PlanSpec parameters, int width, int height) {
  parameters.kind = Plans().Find(name, "plan").kind;
  ValidatePlan(parameters, width, height);
  return parameters;
}

}  // namespace pf
