#pragma once
// Seedable counter-based random numbers.
//
// Determinism contract (docs/design.md, G1): the random numbers of one pixel sample depend only
// on (seed, pixel, sample), those of one photon only on (map seed, photon index) — never on
// threads or scheduling. A `Rng` is therefore never shared: each unit of work derives its own
// stream from a key with `Rng::ForKey`, and then draws sequentially (PCG32, O'Neill 2014).

#include <cstdint>

namespace pf {

// SplitMix64 finaliser: a bijective 64-bit mix with full avalanche.
constexpr uint64_t Mix64(uint64_t z) {
  z += 0x9e3779b97f4a7c15ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

// Hashes a tuple of 64-bit words into one key (order matters).
constexpr uint64_t HashKey(uint64_t a, uint64_t b) {
  return Mix64(a ^ Mix64(b + 0x632be59bd9b4e019ull));
}
constexpr uint64_t HashKey(uint64_t a, uint64_t b, uint64_t c) {
  return HashKey(HashKey(a, b), c);
}
constexpr uint64_t HashKey(uint64_t a, uint64_t b, uint64_t c, uint64_t d) {
  return HashKey(HashKey(a, b, c), d);
}

class Rng {
 public:
  constexpr Rng() : Rng(0, 0) {}
  constexpr Rng(uint64_t state_seed, uint64_t stream) {
    inc_ = (stream << 1u) | 1u;
    state_ = 0;
    NextU32();
    state_ += state_seed;
    NextU32();
  }
  // A stream for a key tuple, e.g. ForKey(HashKey(seed, pixel, sample)).
  static constexpr Rng ForKey(uint64_t key) { return Rng(Mix64(key), Mix64(key ^ 0xda942042e4dd58b5ull)); }

  constexpr uint32_t NextU32() {
    const uint64_t old = state_;
    state_ = old * 6364136223846793005ull + inc_;
    const uint32_t xorshifted = uint32_t(((old >> 18u) ^ old) >> 27u);
    const uint32_t rot = uint32_t(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((~rot + 1u) & 31));
  }
  // Uniform in [0, 1): 24 random mantissa bits, never returns 1.
  constexpr float Uniform() { return float(NextU32() >> 8) * 0x1p-24f; }
  constexpr double UniformDouble() {
    const uint64_t hi = NextU32(), lo = NextU32();
    return double(((hi << 32) | lo) >> 11) * 0x1p-53;
  }
  // Uniform integer in [0, n) without modulo bias (Lemire 2019).
  constexpr uint32_t UniformInt(uint32_t n) {
    uint64_t m = uint64_t(NextU32()) * n;
    uint32_t l = uint32_t(m);
    if (l < n) {
      const uint32_t t = (~n + 1u) % n;
      while (l < t) {
        m = uint64_t(NextU32()) * n;
        l = uint32_t(m);
      }
    }
    return uint32_t(m >> 32);
  }

 private:
  uint64_t state_ = 0;
  uint64_t inc_ = 1;
};

}  // namespace pf
