#include "common/plan/plan_factory.h"

#include <fmt/format.h>

#include "common/core/error.h"
#include "common/core/real_text.h"
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

// " flag=value" of PlanRecordText.
std::string Flag(std::string_view flag, std::string_view value) {
  return fmt::format(" {}={}", flag, value);
}
std::string Flag(std::string_view flag, uint32_t value) {
  return Flag(flag, std::to_string(value));
}
std::string Flag(std::string_view flag, double value) {
  return Flag(flag, RealText(value));
}

std::string RecordMultipleMaps(const PlanSpec& p) {
  return Flag("maps", p.maps) + Flag("spp", p.samples_per_pixel) + Flag("tile", p.tile_size);
}

std::string RecordMapsInTurn(const PlanSpec& p) {
  return Flag("spp", p.samples_per_pixel) + Flag("tile", p.tile_size);
}

std::string RecordSkipping(const PlanSpec& p) {
  return Flag("stride", p.stride) + Flag("rounds", p.rounds) + Flag("spp", p.samples_per_pixel);
}

std::string RecordHierarchical(const PlanSpec& p) {
  std::string out = Flag("levels", p.levels) + Flag("dims", p.dims) + Flag("base-samples", p.base_samples) +
                    Flag("min-samples", p.min_samples) + Flag("decay", p.decay) +
                    Flag("localize-threshold", p.localize_threshold) +
                    Flag("localize-contrast", p.localize_contrast) + Flag("tile", p.tile_size) +
                    Flag("hier-part", p.hierarchy_part == HierarchyPart::kIndirect ? "indirect" : "all");
  if (p.hierarchy_part == HierarchyPart::kIndirect) out += Flag("hier-direct-samples", p.direct_samples);
  return out;
}

std::string RecordProgressive(const PlanSpec& p) {
  return Flag("passes", p.maps) + Flag("spp", p.samples_per_pixel) + Flag("tile", p.tile_size);
}

}  // namespace

const NamedRegistry<PlanEntry>& Plans() {
  using K = PlanKind;
  static const NamedRegistry<PlanEntry> registry(
      "plan",
      {{"multiple-maps", K::kMultipleMaps, ValidateMultipleMaps, DescribeMultipleMaps, RecordMultipleMaps},
       {"maps-in-turn", K::kMapsInTurn, ValidateMapsInTurn, DescribeMapsInTurn, RecordMapsInTurn},
       {"skipping", K::kSkipping, ValidateSkipping, DescribeSkipping, RecordSkipping},
       {"hierarchical", K::kHierarchical, ValidateHierarchicalPlan, DescribeHierarchical, RecordHierarchical},
       {"progressive", K::kProgressive, ValidateProgressive, DescribeProgressive, RecordProgressive}});
  return registry;
}

PlanSpec MakePlan(std::string_view name, PlanSpec parameters, int width, int height) {
  parameters.kind = Plans().Find(name, "plan").kind;
  ValidatePlan(parameters, width, height);
  return parameters;
}

}  // namespace pf
