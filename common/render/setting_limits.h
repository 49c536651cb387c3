#pragma once
// The ranges of the render settings that are also the farm's resource limits (docs/security.md,
// "Limits"): a value above one is refused as RESOURCE_EXHAUSTED rather than INVALID_ARGUMENT
// (proto/limits.h names them with the wire's other limits; the settings table,
// render_settings_table.h, uses them as its rows' ranges).

#include <cstdint>

namespace pf {

inline constexpr uint64_t kMaxPhotonsPerMap = uint64_t(1) << 28;
// Caustic splitting (§4.6): the thesis found 4-20 sufficient; brute force emits S·photons, which
// must stay within kMaxPhotonsPerMap as well.
inline constexpr uint32_t kMaxCausticSplit = 256;
inline constexpr uint32_t kMaxK = 10000;
inline constexpr uint32_t kMaxShadowRays = 4096;  // also the local pass's rays

}  // namespace pf
