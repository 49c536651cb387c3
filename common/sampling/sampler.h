#pragma once
// Where the random numbers of one estimate come from (docs/renderer.md, "Sampling and determinism"): one
// `Sampler` per pixel sample or per photon, asked for numbers by *dimension slot*
// (common/sampling/sample_layout.h), never by call order, so that the same slot means the same decision
// (bounce 2's BSDF direction, the RR test at vertex 1, ...) in every sample of a pixel and every photon of a
// map.
//
//  * kIndependent: every number from the sample's own PCG stream, Rng::ForKey(HashKey(seed,
//    pixel, sample)) (photons: HashKey(map seed, index, "photon")), drawn in call order — the
//    sampler the renderer always had.
//  * kSobol (default): padded, Owen-scrambled, shuffled 2-D Sobol points (Burley 2020,
//    "Practical Hash-based Owen Scrambling"). Every slot is its own 2-D (0,2)-sequence —
//    dimension 0 the van der Corput sequence, dimension 1 the Pascal-matrix generator — at
//    index = the sample's index (pixel sample number; photon number within the map). Per slot
//    and per stream key (seed, pixel) or (map seed) the index is shuffled by a nested uniform
//    scramble of its bits (this maps every aligned block of 2^m indices onto another such block,
//    so the first 2^m points of a slot stay a (0,m,2)-net) and each coordinate is Owen-scrambled
//    with its own seed. The shuffle decorrelates the slots (padding); the scrambles make every
//    point uniformly distributed, so each estimate stays unbiased (randomised QMC), and make
//    streams of different keys (pixels, photon maps, maps of a job) independent.
//    A slot may also be asked for `subs` numbers per sample (N shadow rays, N_lp gather rays):
//    number j of sample i sits at index i·subs + j, so the N numbers of one sample are a net of
//    their own when N is a power of two, and all samples of a pixel together are one as well.
//    Slots beyond the layout's budget (kIndependentSlot), j >= subs and indices >= 2^32 draw from
//    the sample's PCG stream instead.
//
// A value depends only on (kind, key, index, slot, j): never on threads, workers or order.

#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

#if defined(__SSSE3__) && defined(__SSE4_1__)
#include <immintrin.h>
#endif

#include "common/core/rng.h"

namespace pf {

enum class SamplerKind : uint8_t { kSobol = 0, kIndependent = 1 };

// "sobol" / "independent".
const char* SamplerName(SamplerKind kind);
std::optional<SamplerKind> ParseSamplerKind(std::string_view name);

// A slot number that always draws from the independent fallback stream.
inline constexpr uint32_t kIndependentSlot = 0xffffffffu;

struct Sample2 {
  float u = 0, v = 0;
};

namespace sobol {

constexpr uint32_t ReverseBits(uint32_t v) {
  v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
  v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
  v = ((v >> 4) & 0x0f0f0f0fu) | ((v & 0x0f0f0f0fu) << 4);
  return __builtin_bswap32(v);
}

// A hash of v in which output bit k depends only on the seed and the input bits 0..k (every
// operation carries upwards: addition, multiplication by odd numbers, x ^= x·even). Applied to a
// bit-reversed fraction, this flips each binary digit as a function of the digits before it — a
// nested (Owen) scramble; the first step (+ seed) makes the result uniform for a uniform seed.
// The pattern is Laine and Karras's (2011); the constants are ours, checked by the
// scramble-quality tests in tests/common/sampler_test.cpp.
constexpr uint32_t NestedHash(uint32_t v, uint32_t seed) {
  v += seed;
  v ^= v * 0x89025cc0u;
  v ^= v * 0x1c9756ceu;
  v *= (seed >> 15) | 1u;
  return v;
}

// Nested uniform scramble of a 32-bit binary fraction (MSB = first digit): an Owen scramble.
// Also shuffles a sequence index: bits of the index are flipped as functions of the higher bits,
// so every aligned block of 2^m indices maps onto an aligned block of 2^m indices.
constexpr uint32_t OwenScramble(uint32_t x, uint32_t seed) {
  return ReverseBits(NestedHash(ReverseBits(x), seed));
}

// Generator columns of Sobol dimension 1 (the Pascal matrix mod 2), bit-reversed so that bit r
// of column c is C(c, r) mod 2, tabulated per index byte: kPascal[b][t] = XOR of the reversed
// columns 8b + k for the set bits k of t.
//
// kPascalOfReversed: the same products indexed by the bytes of the *bit-reversed* index
// h = ReverseBits(i): XOR of the reversed columns 31 − (8b + k) for the set bits k of t. Point2D
// gets its shuffled index bit-reversed from the hash; reading the Pascal product straight from it
// takes the bit reversal off the y coordinate's latency chain (it only feeds x now).
constexpr std::array<std::array<uint32_t, 256>, 4> MakePascalTables(bool of_reversed_index) {
  std::array<uint32_t, 32> column{};
  column[0] = 1u;
  for (int c = 1; c < 32; ++c) column[c] = column[c - 1] ^ (column[c - 1] << 1);
  std::array<std::array<uint32_t, 256>, 4> t{};
  for (int b = 0; b < 4; ++b)
    for (uint32_t v = 0; v < 256; ++v) {
      uint32_t x = 0;
      for (int k = 0; k < 8; ++k)
        if (v & (1u << k)) x ^= column[of_reversed_index ? 31 - (8 * b + k) : 8 * b + k];
      t[b][v] = x;
    }
  return t;
}
inline constexpr std::array<std::array<uint32_t, 256>, 4> kPascal = MakePascalTables(false);
inline constexpr std::array<std::array<uint32_t, 256>, 4> kPascalOfReversed = MakePascalTables(true);

// Unscrambled Sobol dimensions 0 and 1 of index i, as 32-bit fractions.
constexpr uint32_t VanDerCorput(uint32_t i) {
  return ReverseBits(i);
}
constexpr uint32_t Pascal(uint32_t i) {
  return ReverseBits(kPascal[0][i & 255] ^ kPascal[1][(i >> 8) & 255] ^ kPascal[2][(i >> 16) & 255] ^
                     kPascal[3][i >> 24]);
}

// A 32-bit fraction as a float in [0, 1): its top 24 bits, exactly representable, never 1.
constexpr float ToFloat(uint32_t x) {
  return float(x >> 8) * 0x1p-24f;
}

// The seeds of slot `slot` in the stream `key`: the index shuffle, and per dimension the nested
// scramble and a final digital shift (XOR of a random fraction: a scramble too, and it makes every
// point uniform whatever the nested hash's quality: x's shift comes from bits disjoint from x's
// scramble seed, y's from a second multiply-xorshift round).
struct SlotSeeds1 {
  uint32_t shuffle, x, shift_x;
};
struct SlotSeeds2 {
  uint32_t shuffle, x, shift_x, y, shift_y;
};
// `key` is already a Mix64 output; one multiply-xorshift round spreads the slot over it.
constexpr uint64_t SlotHash(uint64_t key, uint32_t slot) {
  uint64_t h = (key ^ (uint64_t(slot) * 0xd1342543de82ef95ull)) * 0xbf58476d1ce4e5b9ull;
  return h ^ (h >> 31);
}
constexpr SlotSeeds1 Seeds1Of(uint64_t key, uint32_t slot) {
  const uint64_t h = SlotHash(key, slot);
  return {uint32_t(h) * 0x9e3779b9u + 0x7f4a7c15u, uint32_t(h), uint32_t(h >> 32)};
}
constexpr SlotSeeds2 Seeds2Of(uint64_t key, uint32_t slot) {
  const uint64_t h = SlotHash(key, slot);
  const uint64_t g = (h ^ (h >> 29)) * 0x94d049bb133111ebull;
  return {uint32_t(h) * 0x9e3779b9u + 0x7f4a7c15u, uint32_t(h), uint32_t(h >> 32), uint32_t(g),
          uint32_t(g >> 32)};
}

// The scrambled, shuffled points of one slot, as 32-bit fractions, from the bit-reversed index
// (computed once per sample). Written out so that no bit reversal is done twice:
// VanDerCorput(j) = ReverseBits(j), the Owen scramble of a bit-reversed value needs no reversal
// before hashing, and the shuffle OwenScramble(i) = ReverseBits(NestedHash(ReverseBits(i))).
constexpr uint32_t Point1D(uint32_t reversed_index, const SlotSeeds1& s) {
  const uint32_t j = ReverseBits(NestedHash(reversed_index, s.shuffle));
  return ReverseBits(NestedHash(j, s.x) ^ s.shift_x);
}
struct Point2 {
  uint32_t x, y;
};
constexpr Point2 Point2D(uint32_t reversed_index, const SlotSeeds2& s) {
  const uint32_t h = NestedHash(reversed_index, s.shuffle);  // ReverseBits(j)
  const uint32_t j = ReverseBits(h);
  const uint32_t pascal_reversed = kPascalOfReversed[0][h & 255] ^ kPascalOfReversed[1][(h >> 8) & 255] ^
                                   kPascalOfReversed[2][(h >> 16) & 255] ^ kPascalOfReversed[3][h >> 24];
  return {ReverseBits(NestedHash(j, s.x) ^ s.shift_x),
          ReverseBits(NestedHash(pascal_reversed, s.y) ^ s.shift_y)};
}

// Everything of one pixel's stream that does not depend on the sample index: the keys and the
// seeds of the first kPixelSeedSlots slots (the layout's budget, common/sampling/sample_layout.h).
// The renderer computes it once per pixel and hands it to every sample's Sampler, so a number
// costs the three nested hashes of its point and no per-slot key hashing. Values are exactly
// those of Seeds2Of(key, slot): the same image with or without it.
inline constexpr uint32_t kPixelSeedSlots = 19;

// The same seeds as lanes (structure of arrays, padded to a multiple of 4 slots), for
// PointsOfSlots: the points of all precomputed slots of one sample in one pass.
inline constexpr uint32_t kPixelSlotLanes = (kPixelSeedSlots + 3) / 4 * 4;
struct SlotSeedLanes {
  alignas(16) std::array<uint32_t, kPixelSlotLanes> shuffle{}, x{}, shift_x{}, y{}, shift_y{};
};

// Which slot each lane holds. The first kEagerLanes lanes (computed for every sample) hold the
// pixel and, per path vertex, the slots every integrator asks (sample_layout.h offsets 1, 2, 6,
// 7, 8: light triangle and point, BSDF lobe and direction, roulette); the other lanes (light
// stratum, PhotonDirect's extra light sample, gather lobe and direction: only the photon-map
// integrator's estimators ask them) are computed on a sample's first request of one of them.
// Within each group the 2-D slots come first (lanes [0, kEager2D) and [kEagerLanes, kLazy2D)):
// only they need the Pascal product and the y coordinate. Lane 19 is padding (slot 19 is past
// the precomputed ones and never read from a lane).
inline constexpr uint32_t kEagerLanes = 12, kEager2D = 5, kLazy2D = kEagerLanes + 4;
inline constexpr std::array<uint32_t, kPixelSlotLanes> kSlotOfLane = {0,  3, 8, 12, 17, 2,  7, 9,  11, 16,
                                                                      18, 1, 4, 6,  13, 15, 5, 10, 14, 19};
constexpr std::array<uint32_t, kPixelSlotLanes> MakeLaneOfSlot() {
  std::array<uint32_t, kPixelSlotLanes> lane{};
  for (uint32_t k = 0; k < kPixelSlotLanes; ++k) lane[kSlotOfLane[k]] = k;
  return lane;
}
inline constexpr std::array<uint32_t, kPixelSlotLanes> kLaneOfSlot = MakeLaneOfSlot();
// Whether a lane's y coordinate is computed (a 1-D slot asked as 2-D takes the per-request path).
constexpr bool LaneHasY(uint32_t lane) {
  return lane < kEager2D || (lane >= kEagerLanes && lane < kLazy2D);
}

// The photon streams' lanes (PhotonStream, sample_layout.h's photon slots): the slots every photon
// of a closed scene asks — light stratum (0), point (1), direction (2) and the lobe and direction
// slots of bounces 0 and 1 (3–6) — and bounce 2's lobe (7), which fills the second 4-lane group.
// The 2-D slots come first (lanes [0, kPhotonEager2D)). Later bounces (a minority of photons)
// take the per-request path with the stream's precomputed seeds. Wald 1999, §2.2: the emission
// and the first bounces are where every photon spends its random numbers.
inline constexpr uint32_t kPhotonEagerLanes = 8, kPhotonEager2D = 4;
inline constexpr std::array<uint32_t, kPhotonEagerLanes> kPhotonSlotOfLane = {1, 2, 4, 6, 0, 3, 5, 7};
constexpr std::array<uint32_t, kPhotonEagerLanes> MakePhotonLaneOfSlot() {
  std::array<uint32_t, kPhotonEagerLanes> lane{};
  for (uint32_t k = 0; k < kPhotonEagerLanes; ++k) lane[kPhotonSlotOfLane[k]] = k;
  return lane;
}
inline constexpr std::array<uint32_t, kPhotonEagerLanes> kPhotonLaneOfSlot = MakePhotonLaneOfSlot();

// Point2D of every precomputed slot at once, as floats: exactly the values Point2D gives (a 1-D
// slot's number is the x coordinate, exactly Point1D). One pass over independent slots instead
// of one dependent chain of three hashes and three bit reversals per request: the hashes and
// bit reversals run as 4-lane vector code and overlap (the Pascal lookups stay scalar), so a
// sample pays a fraction of the latency it paid asking slot by slot, even though slots the
// integrator never asks (another integrator's, or a path's second vertex after it ended) are
// computed too.
// Lanes [First, Last) only (see kSlotOfLane); v only for the 2-D lanes [First, Last2D).
#if defined(__SSSE3__) && defined(__SSE4_1__)
// 4-lane forms of NestedHash, ReverseBits and ToFloat (SSE4.1 / SSSE3, in the x86-64-v2
// baseline): the same bits as the scalar functions. GCC's own vectorisation of the loops below
// reversed bits with 15 shifts and masks per vector and spilled every step to the stack; here a
// bit reversal is two nibble lookups and a byte shuffle (pshufb): with the photon lanes read
// inline, 62.0 → 57.0 M instructions for a 20k-photon Cornell trace (docs/results/kernel.md §4).
inline __m128i NestedHash4(__m128i v, __m128i seed) {
  v = _mm_add_epi32(v, seed);
  v = _mm_xor_si128(v, _mm_mullo_epi32(v, _mm_set1_epi32(int(0x89025cc0u))));
  v = _mm_xor_si128(v, _mm_mullo_epi32(v, _mm_set1_epi32(int(0x1c9756ceu))));
  return _mm_mullo_epi32(v, _mm_or_si128(_mm_srli_epi32(seed, 15), _mm_set1_epi32(1)));
}
inline __m128i ReverseBits4(__m128i v) {
  const __m128i nibble = _mm_set1_epi8(0x0f);
  // A byte's reversal is (its low nibble reversed) << 4 | (its high nibble reversed).
  const __m128i low_reversed_high =
      _mm_setr_epi8(0x00, char(0x80), 0x40, char(0xc0), 0x20, char(0xa0), 0x60, char(0xe0), 0x10, char(0x90),
                    0x50, char(0xd0), 0x30, char(0xb0), 0x70, char(0xf0));
  const __m128i high_reversed_low =
      _mm_setr_epi8(0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf);
  const __m128i low = _mm_and_si128(v, nibble), high = _mm_and_si128(_mm_srli_epi16(v, 4), nibble);
  const __m128i bytes =
      _mm_or_si128(_mm_shuffle_epi8(low_reversed_high, low), _mm_shuffle_epi8(high_reversed_low, high));
  return _mm_shuffle_epi8(bytes, _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12));
}
inline __m128 ToFloat4(__m128i x) {
  return _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(x, 8)), _mm_set1_ps(0x1p-24f));
}
inline __m128i Load4(const uint32_t* p) {
  return _mm_load_si128(reinterpret_cast<const __m128i*>(p));
}
#endif

template <uint32_t First, uint32_t Last, uint32_t Last2D>
inline void PointsOfSlots(uint32_t reversed_index, const SlotSeedLanes& s, float* u, float* v) {
#if defined(__SSSE3__) && defined(__SSE4_1__)
  // Groups of 4 lanes (First and Last are multiples of 4); the y coordinates of a group's lanes
  // past Last2D are computed too and never read (LaneHasY).
  static_assert(First % 4 == 0 && Last % 4 == 0 && Last2D <= Last);
  const __m128i index = _mm_set1_epi32(int(reversed_index));
  for (uint32_t k = First; k < Last; k += 4) {
    const __m128i h = NestedHash4(index, Load4(&s.shuffle[k]));
    const __m128i x = NestedHash4(ReverseBits4(h), Load4(&s.x[k]));
    _mm_storeu_ps(u + k, ToFloat4(ReverseBits4(_mm_xor_si128(x, Load4(&s.shift_x[k])))));
    if (k < Last2D) {
      alignas(16) uint32_t hs[4], pascal_reversed[4];
      _mm_store_si128(reinterpret_cast<__m128i*>(hs), h);
      for (int l = 0; l < 4; ++l)
        pascal_reversed[l] = kPascalOfReversed[0][hs[l] & 255] ^ kPascalOfReversed[1][(hs[l] >> 8) & 255] ^
                             kPascalOfReversed[2][(hs[l] >> 16) & 255] ^ kPascalOfReversed[3][hs[l] >> 24];
      const __m128i y = NestedHash4(Load4(pascal_reversed), Load4(&s.y[k]));
      _mm_storeu_ps(v + k, ToFloat4(ReverseBits4(_mm_xor_si128(y, Load4(&s.shift_y[k])))));
    }
  }
#else
  alignas(16) std::array<uint32_t, kPixelSlotLanes> h, j, pascal_reversed;
  for (uint32_t k = First; k < Last; ++k) {
    h[k] = NestedHash(reversed_index, s.shuffle[k]);
    j[k] = ReverseBits(h[k]);
  }
  for (uint32_t k = First; k < Last; ++k)
    u[k] = ToFloat(ReverseBits(NestedHash(j[k], s.x[k]) ^ s.shift_x[k]));
  for (uint32_t k = First; k < Last2D; ++k)
    pascal_reversed[k] = kPascalOfReversed[0][h[k] & 255] ^ kPascalOfReversed[1][(h[k] >> 8) & 255] ^
                         kPascalOfReversed[2][(h[k] >> 16) & 255] ^ kPascalOfReversed[3][h[k] >> 24];
  for (uint32_t k = First; k < Last2D; ++k)
    v[k] = ToFloat(ReverseBits(NestedHash(pascal_reversed[k], s.y[k]) ^ s.shift_y[k]));
#endif
}

// The points of numbers j = 0 .. subs−1 of sample `index` in one slot (sequence indices
// index·subs + j), as floats: exactly Point2D's values (u alone, Point1D's, when v is null).
// 2 <= subs <= kMaxSubIndices, index·subs + subs − 1 < 2^32. For a power-of-two subs the
// reversed index of number j is ReverseBits(index) >> log2(subs) | ReverseBits(j), which takes
// one of the three bit reversals off every number. Compiled twice (sampler.cpp): for the build's
// baseline (4 lanes) and for AVX2 (8 lanes), chosen at load time by the CPU.
inline constexpr uint32_t kMaxSubIndices = 32;
void PointsOfSubIndices(uint32_t index, uint32_t subs, const SlotSeeds2& s, float* u, float* v);

}  // namespace sobol

class Sampler;

// Per-pixel state of the pixel-sample streams (see sobol::kPixelSeedSlots).
class PixelStream {
 public:
  PixelStream(SamplerKind kind, uint64_t seed, uint32_t pixel)
      : kind_(kind), pixel_key_(HashKey(seed, pixel)), key_(Mix64(pixel_key_ ^ kPixelTag)) {
    if (kind_ == SamplerKind::kSobol)
      for (uint32_t slot = 0; slot < sobol::kPixelSeedSlots; ++slot) {
        const sobol::SlotSeeds2 t = seeds_[slot] = sobol::Seeds2Of(key_, slot);
        const uint32_t lane = sobol::kLaneOfSlot[slot];
        lanes_.shuffle[lane] = t.shuffle;
        lanes_.x[lane] = t.x;
        lanes_.shift_x[lane] = t.shift_x;
        lanes_.y[lane] = t.y;
        lanes_.shift_y[lane] = t.shift_y;
      }
  }

 private:
  friend class Sampler;
  static constexpr uint64_t kPixelTag = 0x736f626f6c;  // "sobol"

  SamplerKind kind_;
  uint64_t pixel_key_, key_;
  std::array<sobol::SlotSeeds2, sobol::kPixelSeedSlots> seeds_{};
  sobol::SlotSeedLanes lanes_;
};

// Per-map state of the photon streams: the map's key and the seeds of the first
// sobol::kPixelSeedSlots slots — exactly the photon layout's light, point and direction slots
// and the lobe and direction slots of the kPhotonBounceBudget budgeted bounces
// (sample_layout.h). Without it every request of a photon recomputes its slot's seeds from the
// key (a 64-bit multiply-xorshift round or two per number, the same for all photons of the map);
// the photon tracer computes them once per map. Values are exactly those of
// Sampler::ForPhoton(kind, map_seed, i): the same map with or without it.
//
// A photon's lanes can also be computed ahead (Lanes) and handed to ForPhoton: a caller tracing
// many photons in a row (the photon tracer) computes a batch of photons' lanes in one loop, where
// the photons' hash chains overlap. Computed inside ForPhoton, one photon's chain (three dependent
// vector multiplies per hash, ~150 cycles) was a latency its walk waited for before its first ray
// (docs/results/kernel.md §4).
struct PhotonLanes {
  alignas(16) std::array<float, sobol::kPhotonEagerLanes> u;
  alignas(16) std::array<float, sobol::kPhotonEager2D> v;  // the 2-D lanes' y
};
static_assert(sobol::kPhotonEager2D == 4, "PointsOfSlots writes y for one group of 4 lanes");

class PhotonStream {
 public:
  PhotonStream(SamplerKind kind, uint64_t map_seed);

  // Whether ForPhoton(*this, photon) reads lanes (the Sobol kind, a 32-bit index).
  bool HasLanes(uint64_t photon) const { return kind_ == SamplerKind::kSobol && !(photon >> 32); }
  // The lanes of `photon` (HasLanes(photon)): what ForPhoton(*this, photon) computes.
  void Lanes(uint64_t photon, PhotonLanes* lanes) const {
    sobol::PointsOfSlots<0, sobol::kPhotonEagerLanes, sobol::kPhotonEager2D>(
        sobol::ReverseBits(uint32_t(photon)), lanes_, lanes->u.data(), lanes->v.data());
  }

 private:
  friend class Sampler;
  SamplerKind kind_;
  uint64_t map_seed_, key_;
  std::array<sobol::SlotSeeds2, sobol::kPixelSeedSlots> seeds_{};
  sobol::SlotSeedLanes lanes_;  // the seeds of the photon lanes [0, kPhotonEagerLanes)
};

class Sampler {
 public:
  // Sample `sample` of pixel `pixel` (y·W + x) of the stream family `seed` (a job's pixel seed).
  // The independent stream is Rng::ForKey(HashKey(seed, pixel, sample)), as it always was.
  static Sampler ForPixelSample(SamplerKind kind, uint64_t seed, uint32_t pixel, uint32_t sample) {
    const uint64_t pixel_key = HashKey(seed, pixel);
    return Sampler(kind, Mix64(pixel_key ^ PixelStream::kPixelTag), sample, HashKey(pixel_key, sample));
  }
  // The same sampler (the same values) from the pixel's precomputed state; `pixel` must outlive it.
  static Sampler ForPixelSample(const PixelStream& pixel, uint32_t sample) {
    Sampler s(pixel.kind_, pixel.key_, sample, HashKey(pixel.pixel_key_, sample));
    s.seeds_ = pixel.seeds_.data();
    if (s.kind_ == SamplerKind::kSobol) {
      s.lanes_ = &pixel.lanes_;
      sobol::PointsOfSlots<0, sobol::kEagerLanes, sobol::kEager2D>(s.reversed_index_, pixel.lanes_,
                                                                   s.slot_u_.data(), s.slot_v_.data());
    }
    return s;
  }
  // Photon `photon` of the photon map traced with `map_seed`; independent stream
  // Rng::ForKey(HashKey(map_seed, photon, "photon")) as before.
  static Sampler ForPhoton(SamplerKind kind, uint64_t map_seed, uint64_t photon) {
    return Sampler(photon >> 32 ? SamplerKind::kIndependent : kind, HashKey(map_seed, kPhotonTag),
                   uint32_t(photon), HashKey(map_seed, photon, kPhotonTag));
  }
  // The same sampler (the same values) from the map's precomputed state; `stream` must outlive it.
  // The Sobol kind computes the photon lanes (sobol::kPhotonSlotOfLane) in one vector pass, as
  // ForPixelSample does for a sample's eager slots: one pass over 8 independent slots instead of
  // a dependent chain of hashes and bit reversals per request (docs/results/kernel.md §4).
  static Sampler ForPhoton(const PhotonStream& stream, uint64_t photon) {
    Sampler s = ForPhotonWithoutLanes(stream, photon);
    if (s.photon_lanes_)
      sobol::PointsOfSlots<0, sobol::kPhotonEagerLanes, sobol::kPhotonEager2D>(
          s.reversed_index_, stream.lanes_, s.slot_u_.data(), s.slot_v_.data());
    return s;
  }
  // The same sampler from lanes computed ahead: `lanes` must be stream.Lanes(photon)
  // (stream.HasLanes(photon)).
  static Sampler ForPhoton(const PhotonStream& stream, uint64_t photon, const PhotonLanes& lanes) {
    Sampler s = ForPhotonWithoutLanes(stream, photon);
    std::copy(lanes.u.begin(), lanes.u.end(), s.slot_u_.begin());
    std::copy(lanes.v.begin(), lanes.v.end(), s.slot_v_.begin());
    return s;
  }

  // Number j of `subs` in slot `slot` (see the header comment), uniform in [0, 1).
  // The independent kind and the fallback slots take the first branch's test only.
  // A photon lane (photon_lanes_ implies the Sobol kind; subs == 1 implies j == 0) is read
  // inline; everything else takes the out-of-line general path, which GCC does not inline (the
  // photon walk called it for each of its numbers, docs/results/kernel.md §4).
  float Get1D(uint32_t slot, uint32_t j = 0, uint32_t subs = 1) {
    if (subs == 1 && j == 0 && IsPhotonLane(slot)) return slot_u_[sobol::kPhotonLaneOfSlot[slot]];
    return Get1DGeneral(slot, j, subs);
  }
  Sample2 Get2D(uint32_t slot, uint32_t j = 0, uint32_t subs = 1) {
    if (subs == 1 && j == 0 && IsPhotonLane2D(slot)) return PhotonLane2D(slot);
    return Get2DGeneral(slot, j, subs);
  }
  // Get1D(slot) / Get2D(slot), forced inline: in the photon walk GCC's budget otherwise keeps
  // Get1D and Get2D themselves out of line, a call per number; forcing those two inline
  // everywhere made GCC stop inlining their general path into the camera sample loop instead
  // (+3 % instructions of a path-traced image), so the walk has its own.
  [[gnu::always_inline]] float PhotonGet1D(uint32_t slot) {
    if (IsPhotonLane(slot)) return slot_u_[sobol::kPhotonLaneOfSlot[slot]];
    return Get1DGeneral(slot, 0, 1);
  }
  [[gnu::always_inline]] Sample2 PhotonGet2D(uint32_t slot) {
    if (IsPhotonLane2D(slot)) return PhotonLane2D(slot);
    return Get2DGeneral(slot, 0, 1);
  }

 private:
  // Whether number 0 of `slot` is read from the photon lanes (photon_lanes_ implies the Sobol
  // kind), as 1-D or as 2-D (only the first kPhotonEager2D lanes hold y).
  bool IsPhotonLane(uint32_t slot) const { return photon_lanes_ && slot < sobol::kPhotonEagerLanes; }
  bool IsPhotonLane2D(uint32_t slot) const {
    return IsPhotonLane(slot) && sobol::kPhotonLaneOfSlot[slot] < sobol::kPhotonEager2D;
  }
  Sample2 PhotonLane2D(uint32_t slot) const {
    const uint32_t lane = sobol::kPhotonLaneOfSlot[slot];
    return {slot_u_[lane], slot_v_[lane]};
  }

  // Everything the inline readers above leave: the pixel lanes, the per-request points,
  // sub-indexed numbers and the independent stream (photon lanes never reach here).
  float Get1DGeneral(uint32_t slot, uint32_t j, uint32_t subs) {
    if (kind_ == SamplerKind::kSobol && slot != kIndependentSlot && j < subs) {
      if (subs == 1) {
        if (lanes_ && slot < sobol::kPixelSeedSlots) return slot_u_[Lane(slot)];
        return sobol::ToFloat(sobol::Point1D(reversed_index_, SeedsOf1(slot)));
      }
      if (const SubBatch* b = Batch(slot, subs, false)) return b->u[j];
      if (const std::optional<uint32_t> reversed = ReversedSubIndex(j, subs))
        return sobol::ToFloat(sobol::Point1D(*reversed, SeedsOf1(slot)));
    }
    return rng().Uniform();
  }
  Sample2 Get2DGeneral(uint32_t slot, uint32_t j, uint32_t subs) {
    if (kind_ == SamplerKind::kSobol && slot != kIndependentSlot && j < subs) {
      if (subs == 1) {
        if (lanes_ && slot < sobol::kPixelSeedSlots && sobol::LaneHasY(sobol::kLaneOfSlot[slot])) {
          const uint32_t lane = Lane(slot);
          return {slot_u_[lane], slot_v_[lane]};
        }
        return ToSample(sobol::Point2D(reversed_index_, SeedsOf2(slot)));
      }
      if (const SubBatch* b = Batch(slot, subs, true)) return {b->u[j], b->v[j]};
      if (const std::optional<uint32_t> reversed = ReversedSubIndex(j, subs))
        return ToSample(sobol::Point2D(*reversed, SeedsOf2(slot)));
    }
    const float u = rng().Uniform();
    return {u, rng().Uniform()};
  }

 public:
  // The independent stream, for choices outside the layout (e.g. an exact UniformInt). Seeded on
  // first use: a Sobol sample whose slots are all within the budget never pays for it.
  Rng& rng() {
    if (!rng_ready_) {
      if (rng_key_pending_) rng_key_ = HashKey(rng_key_, rng_key_photon_, kPhotonTag);
      rng_ = Rng::ForKey(rng_key_);
      rng_ready_ = true;
    }
    return rng_;
  }
  SamplerKind kind() const { return kind_; }

 private:
  static constexpr uint64_t kPhotonTag = 0x70686f746f6eull;  // "photon", as the photon tracer's key

  Sampler(SamplerKind kind, uint64_t key, uint32_t index, uint64_t rng_key)
      : kind_(kind),
        index_(index),
        reversed_index_(sobol::ReverseBits(index)),
        key_(key),
        rng_key_(rng_key) {}

  // The lane of a precomputed slot, computing the lazy lanes on the sample's first request.
  uint32_t Lane(uint32_t slot) {
    const uint32_t lane = sobol::kLaneOfSlot[slot];
    if (lane >= sobol::kEagerLanes && !lazy_lanes_ready_) {
      sobol::PointsOfSlots<sobol::kEagerLanes, sobol::kPixelSlotLanes, sobol::kLazy2D>(
          reversed_index_, *lanes_, slot_u_.data(), slot_v_.data());
      lazy_lanes_ready_ = true;
    }
    return lane;
  }

  // Sub-indexed numbers (N shadow rays, N_lp gather rays: Get*D(slot, j, subs) with 1 < subs <=
  // kMaxBatch) are computed for all j < subs of a slot in one pass on the first request and read
  // from here after: the same values as the per-request path (Point1D / Point2D at index
  // index·subs + j), but the chains of the N numbers run side by side as vector code instead of
  // one after the other. Direct-mapped by slot: the slots one vertex asks with sub-indices (light
  // stratum, triangle, point; gather lobe, direction: sample_layout.h offsets 0, 1, 2, 4, 5 of
  // 9) fall into different entries; a conflict only recomputes.
  static constexpr uint32_t kMaxBatch = sobol::kMaxSubIndices, kBatches = 8;
  // An entry is read only once its bit in batches_filled_ is set: a Sampler is made for every
  // photon and camera sample, and most never ask a sub-indexed number, so nothing of the ~2 KiB
  // of entries is written up front (the eight headers' initialisation was 0.6 % of a photon walk's
  // instructions). Like slot_u_/slot_v_, unfilled entries are copied with the Sampler unread.
  struct SubBatch {
    uint32_t slot, subs;
    bool two_d;
    std::array<float, kMaxBatch> u, v;
  };
  // Sobol kind, slot within the layout, 2 <= subs, j < subs (the caller checked).
  const SubBatch* Batch(uint32_t slot, uint32_t subs, bool two_d) {
    if (subs > kMaxBatch || (uint64_t(index_) * subs + subs - 1) >> 32) return nullptr;
    const uint32_t entry = slot % kBatches;
    SubBatch& b = batches_[entry];
    if ((batches_filled_ >> entry & 1u) && b.slot == slot && b.subs == subs && (b.two_d || !two_d)) return &b;
    sobol::PointsOfSubIndices(index_, subs, SeedsOf2(slot), b.u.data(), two_d ? b.v.data() : nullptr);
    b.slot = slot;
    b.subs = subs;
    b.two_d = two_d;
    batches_filled_ |= 1u << entry;
    return &b;
  }

  // The bit-reversed sequence index of number j < subs (index·subs + j), if below 2^32.
  std::optional<uint32_t> ReversedSubIndex(uint32_t j, uint32_t subs) const {
    const uint64_t i = uint64_t(index_) * subs + j;
    if (i >> 32) return std::nullopt;
    return sobol::ReverseBits(uint32_t(i));
  }
  sobol::SlotSeeds2 SeedsOf2(uint32_t slot) const {
    return seeds_ && slot < sobol::kPixelSeedSlots ? seeds_[slot] : sobol::Seeds2Of(key_, slot);
  }
  sobol::SlotSeeds1 SeedsOf1(uint32_t slot) const {
    if (seeds_ && slot < sobol::kPixelSeedSlots) {
      const sobol::SlotSeeds2& t = seeds_[slot];
      return {t.shuffle, t.x, t.shift_x};
    }
    return sobol::Seeds1Of(key_, slot);
  }
  static Sample2 ToSample(sobol::Point2 p) { return {sobol::ToFloat(p.x), sobol::ToFloat(p.y)}; }

  // ForPhoton's sampler before its lanes are filled in. The fallback stream's key,
  // HashKey(map seed, photon, "photon"), is hashed on the stream's first use (rng()): a photon
  // whose numbers all come from the budget's slots never needs it.
  static Sampler ForPhotonWithoutLanes(const PhotonStream& stream, uint64_t photon) {
    Sampler s(photon >> 32 ? SamplerKind::kIndependent : stream.kind_, stream.key_, uint32_t(photon),
              stream.map_seed_);
    s.rng_key_photon_ = photon;
    s.rng_key_pending_ = true;
    s.seeds_ = stream.seeds_.data();
    s.photon_lanes_ = s.kind_ == SamplerKind::kSobol;
    return s;
  }

  SamplerKind kind_;
  bool rng_ready_ = false;
  // ForPhoton(PhotonStream): rng_key_ holds the map seed until rng() hashes the key from it.
  bool rng_key_pending_ = false;
  uint32_t index_, reversed_index_;
  uint64_t key_, rng_key_;
  uint64_t rng_key_photon_ = 0;
  const sobol::SlotSeeds2* seeds_ = nullptr;  // a PixelStream's seeds of the first kPixelSeedSlots slots
  // Set for a pixel sample of the Sobol kind: slot_u_/slot_v_ hold the points of the lanes
  // [0, kEagerLanes) and, once computed, of the lazy groups (by sobol::kLaneOfSlot).
  const sobol::SlotSeedLanes* lanes_ = nullptr;
  bool lazy_lanes_ready_ = false;
  // Set for a photon of the Sobol kind: slot_u_/slot_v_ hold the photon lanes (sobol::kPhotonSlotOfLane).
  bool photon_lanes_ = false;
  std::array<float, sobol::kPixelSlotLanes> slot_u_, slot_v_;
  std::array<SubBatch, kBatches> batches_;
  uint32_t batches_filled_ = 0;  // bit e: batches_[e] holds a batch
  Rng rng_;

  friend class PhotonStream;
};

inline PhotonStream::PhotonStream(SamplerKind kind, uint64_t map_seed)
    : kind_(kind), map_seed_(map_seed), key_(HashKey(map_seed, Sampler::kPhotonTag)) {
  for (uint32_t slot = 0; slot < sobol::kPixelSeedSlots; ++slot) seeds_[slot] = sobol::Seeds2Of(key_, slot);
  for (uint32_t lane = 0; lane < sobol::kPhotonEagerLanes; ++lane) {
    const sobol::SlotSeeds2& t = seeds_[sobol::kPhotonSlotOfLane[lane]];
    lanes_.shuffle[lane] = t.shuffle;
    lanes_.x[lane] = t.x;
    lanes_.shift_x[lane] = t.shift_x;
    lanes_.y[lane] = t.y;
    lanes_.shift_y[lane] = t.shift_y;
  }
}

}  // namespace pf
