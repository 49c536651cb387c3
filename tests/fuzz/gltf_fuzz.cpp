// libFuzzer target for the glTF 2.0 loader (tinygltf plus our checks and mapping: gltf_document,
// gltf_accessors, gltf_loader, gltf_materials, gltf_lights). The contract: for any input, LoadGltf
// either returns a scene whose indices are all in range and whose positions are finite, or throws
// pf::InputError. Anything else (another exception, a crash, a sanitizer report, a hang) is a
// finding. Inputs starting with the GLB magic "glTF" are loaded as .glb, others as .gltf.
// External buffers resolve only inside the current directory (the scene root); run_mgf_fuzz.sh
// runs this from a scratch folder holding a small m.bin, and the root check is part of what is
// fuzzed.

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "common/core/error.h"
#include "common/scene/gltf_loader.h"
#include "tests/fuzz/scene_invariants.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const std::filesystem::path file =
      std::filesystem::current_path() / (binary ? "fuzz-input.glb" : "fuzz-input.gltf");
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  }
  // The MGF target's bounds: a 4 KB input stays far below them, but a bug must not make it slow;
  // images (data: URIs whose headers claim any size) at most 2^20 pixels, within libFuzzer's RSS limit.
  static const pf::SceneBudget budget{
      .max_triangles = 50'000, .max_vertices = 150'000, .max_texels = 1 << 20};
  try {
    const pf::SceneDescription scene = pf::LoadGltf(file, {}, budget);
    pf::fuzz::TrapUnlessWellFormed(scene);
    for (const pf::PunctualLight& l : scene.punctual_lights)
      if (!l.intensity.IsFinite() || l.light >= scene.num_lights) __builtin_trap();
  } catch (const pf::InputError&) {
    // Rejected input: the expected outcome for most mutations.
  }
  return 0;
}
