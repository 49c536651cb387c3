// libFuzzer target for the MGF loader. The contract under test: for any input, LoadMgfFromString
// either returns a scene or throws pf::InputError. Any other exception, a crash, a sanitizer
// report, a hang or a huge allocation is a finding.
//
// Includes are resolved against the current directory and may not leave it (include_root), so
// run the fuzzer from a scratch directory; run_mgf_fuzz.sh prepares one with a few files the
// seeds include. Resource limits are lowered so that array/tessellation blow-ups are reported
// quickly as InputError instead of timing out.

#include <spdlog/spdlog.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

#include "common/core/error.h"
#include "common/scene/mgf_loader.h"

namespace {

pf::MgfOptions FuzzOptions() {
  pf::MgfOptions o;
  o.curve_segments = 8;
  o.budget.max_triangles = 50'000;
  o.budget.max_vertices = 150'000;
  o.budget.max_entities = 50'000;
  o.max_depth = 16;
  std::error_code ec;
  o.include_root = std::filesystem::current_path(ec);
  if (ec) o.include_root = ".";
  return o;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const pf::MgfOptions options = FuzzOptions();
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const pf::SceneDescription scene = pf::LoadMgfFromString(text, "fuzz.mgf", options);
    // Cheap invariants of the output: every index in range, one material/light per triangle.
    if (scene.triangle_material.size() != scene.triangles.size() ||
        scene.triangle_light.size() != scene.triangles.size() ||
        (!scene.normals.empty() && scene.normals.size() != scene.positions.size())) {
      __builtin_trap();
    }
    for (size_t t = 0; t < scene.triangles.size(); ++t) {
      for (uint32_t v : scene.triangles[t]) {
        if (v >= scene.positions.size()) __builtin_trap();
      }
      if (scene.triangle_material[t] >= scene.materials.size()) __builtin_trap();
      const uint32_t light = scene.triangle_light[t];
      if (light != pf::kNoLight && light >= scene.num_lights) __builtin_trap();
    }
    for (const pf::Vec3& p : scene.positions) {
      if (!pf::IsFinite(p)) __builtin_trap();
    }
  } catch (const pf::InputError&) {
    // Expected for malformed input.
  }
  return 0;
}
