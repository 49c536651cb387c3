#include "common/sampling/sampler.h"

#include <bit>

namespace pf {

namespace sobol {
namespace {

constexpr std::array<uint32_t, kMaxSubIndices> MakeReversedSmall() {
  std::array<uint32_t, kMaxSubIndices> r{};
  for (uint32_t k = 0; k < kMaxSubIndices; ++k) r[k] = ReverseBits(k);
  return r;
}
constexpr std::array<uint32_t, kMaxSubIndices> kReversedSmall = MakeReversedSmall();

}  // namespace

// The loops are written lane by lane over independent numbers so that they vectorise (the
// hashes are 32-bit multiplies and xors, the bit reversals byte shuffles); the Pascal lookups
// stay scalar.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((target_clones("arch=x86-64-v3", "default")))
#endif
void PointsOfSubIndices(uint32_t index, uint32_t subs, const SlotSeeds2& s, float* u, float* v) {
  alignas(32) std::array<uint32_t, kMaxSubIndices> h, j;
  if ((subs & (subs - 1)) == 0) {
    const uint32_t high = ReverseBits(index) >> std::countr_zero(subs);
    for (uint32_t k = 0; k < subs; ++k) h[k] = NestedHash(high | kReversedSmall[k], s.shuffle);
  } else {
    const uint32_t first = index * subs;
    for (uint32_t k = 0; k < subs; ++k) h[k] = NestedHash(ReverseBits(first + k), s.shuffle);
  }
  for (uint32_t k = 0; k < subs; ++k) j[k] = ReverseBits(h[k]);
  for (uint32_t k = 0; k < subs; ++k) u[k] = ToFloat(ReverseBits(NestedHash(j[k], s.x) ^ s.shift_x));
  if (!v) return;
  for (uint32_t k = 0; k < subs; ++k)
    j[k] = kPascalOfReversed[0][h[k] & 255] ^ kPascalOfReversed[1][(h[k] >> 8) & 255] ^
           kPascalOfReversed[2][(h[k] >> 16) & 255] ^ kPascalOfReversed[3][h[k] >> 24];
  for (uint32_t k = 0; k < subs; ++k) v[k] = ToFloat(ReverseBits(NestedHash(j[k], s.y) ^ s.shift_y));
}

}  // namespace sobol

const char* SamplerName(SamplerKind kind) {
  return kind == SamplerKind::kSobol ? "sobol" : "independent";
}

std::optional<SamplerKind> ParseSamplerKind(std::string_view name) {
  if (name == "sobol") return SamplerKind::kSobol;
  if (name == "independent") return SamplerKind::kIndependent;
  return std::nullopt;
}

}  // namespace pf
