#pragma once
// A uniform number in [0, 1) from (cell, sample, dimension) alone: splitmix64 of their mix. For the
// integrator's pilots (light_reach.h, caustic_reach.h), which need no sampler state and must give
// the same answer on any thread count.

#include <cstdint>

namespace pf {

inline float HashedUniform(uint64_t cell, uint64_t sample, uint64_t dim) {
  uint64_t z =
      cell * 0x9e3779b97f4a7c15ull + sample * 0xbf58476d1ce4e5b9ull + dim * 0x94d049bb133111ebull + 1;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  z ^= z >> 31;
  return float(z >> 40) * 0x1.0p-24f;
}

}  // namespace pf
