// libFuzzer target for the OBJ loader (tinyobjloader plus our checks and mapping). The contract:
// for any input, LoadObj either returns a scene whose indices are all in range and whose
// positions are finite, or throws pf::InputError. Anything else (another exception, a crash, a
// sanitizer report, a hang) is a finding. `mtllib` references must stay inside the current
// directory (the scene root); run_mgf_fuzz.sh runs this from a scratch folder holding a
// small MTL file, and the root check is part of what is fuzzed.

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>

#include "common/core/error.h"
#include "common/scene/obj_loader.h"
#include "tests/fuzz/scene_invariants.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  // LoadObj reads a file (tinyobjloader resolves `mtllib` next to it).
  static const std::filesystem::path file = std::filesystem::current_path() / "fuzz-input.obj";
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  try {
    const pf::SceneDescription scene = pf::LoadObj(file);
    pf::fuzz::TrapUnlessWellFormed(scene);
  } catch (const pf::InputError&) {
    // Rejected input: the expected outcome for most mutations.
  }
  return 0;
}
