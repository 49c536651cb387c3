#pragma once
// The options of an MGF load and what it reports back (mgf_loader.h): apart from LoadMgf so that
// the interpreter behind it (mgf_reader.h) needs no include of the loader's interface.

#include <cstdint>
#include <filesystem>

#include "common/scene/scene_budget.h"

namespace pf {

// What a load expanded to: the expansion computed before execution and what was executed (also
// when the load fails; for tests and tools).
struct MgfLoadCounts {
  SceneExpansion expected;         // computed before the first entity is executed
  uint64_t executed_entities = 0;  // entities the interpreter executed
  uint64_t emitted_triangles = 0;
};

struct MgfOptions {
  // Segments per full circle of sph/cyl/cone/ring/torus (the tessellation rule of mgf_loader.h).
  // Must be in [3, 1024]; anything else is rejected as an absurd tessellation request.
  int curve_segments = 24;
  // Budgets, so that a small malicious file (nested `-a` arrays, huge tessellations) fails with
  // an InputError before the work instead of exhausting memory or time.
  SceneBudget budget;
  int max_depth = 64;  // include nesting and xf nesting, each
  // If non-empty, every included file must resolve (after symlinks) inside this directory
  // (scene_reference.h). LoadScene sets it to the scene's root folder (the bundle directory on
  // the farm, the entry file's folder for local files); empty = no confinement.
  std::filesystem::path include_root;
  MgfLoadCounts* counts = nullptr;  // if set, receives the counts of the load
};

}  // namespace pf
