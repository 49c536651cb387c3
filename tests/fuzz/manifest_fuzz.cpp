// libFuzzer target for the scene manifest parser (docs/scene-manifest.md). The contract: for any
// input, ParseManifest either returns a manifest whose numbers are finite and in range or throws
// pf::InputError. Anything else (nlohmann's own exceptions escaping, a crash, a sanitizer
// report, a hang) is a finding.

#include <spdlog/spdlog.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "common/core/error.h"
#include "common/scene/manifest.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const pf::SceneManifest m = pf::ParseManifest(text, "scene/fuzz.json");
    if (!(m.scale > 0.0) || !std::isfinite(m.scale)) __builtin_trap();
    if (m.geometry_reference.empty()) __builtin_trap();
    for (const pf::CameraSpec& c : m.cameras) {
      if (!std::isfinite(c.vfov_degrees) || !(c.vfov_degrees > 0.0f) || !(c.vfov_degrees < 180.0f))
        __builtin_trap();
      if (c.width <= 0 || c.height <= 0) __builtin_trap();
    }
  } catch (const pf::InputError&) {
  }
  return 0;
}
