// The samplers of common/sampling (docs/renderer.md, "Sampling and determinism"): stratification of the Sobol
// points (and its absence for the independent sampler), uniformity, independence of streams with different
// keys (photon maps, pixels), the scramble's quality, and order-independence.
#include "common/sampling/sampler.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <set>
#include <vector>

#include "common/sampling/sample_layout.h"

namespace pf {
namespace {

// The first n points of slot `slot` of one pixel's stream, one per pixel sample.
std::vector<Sample2> PixelPoints(SamplerKind kind, uint64_t seed, uint32_t pixel, uint32_t slot, uint32_t n) {
  std::vector<Sample2> p;
  for (uint32_t i = 0; i < n; ++i) p.push_back(Sampler::ForPixelSample(kind, seed, pixel, i).Get2D(slot));
  return p;
}

// True if every elementary interval [a/2^k, (a+1)/2^k) x [b/2^(m-k), (b+1)/2^(m-k)), k = 0..m,
// holds exactly one of the 2^m points: a (0,m,2)-net in base 2.
bool IsNet(const std::vector<Sample2>& points, int m) {
  if (points.size() != (size_t(1) << m)) return false;
  for (int k = 0; k <= m; ++k) {
    std::vector<int> count(points.size(), 0);
    for (const Sample2& p : points) {
      const uint32_t a = uint32_t(std::ldexp(double(p.u), k));
      const uint32_t b = uint32_t(std::ldexp(double(p.v), m - k));
      ++count[(size_t(a) << (m - k)) | b];
    }
    for (int c : count)
      if (c != 1) return false;
  }
  return true;
}

bool IsStratified1D(const std::vector<float>& values, int m) {
  std::vector<int> count(size_t(1) << m, 0);
  for (float v : values) ++count[size_t(std::ldexp(double(v), m))];
  for (int c : count)
    if (c != 1) return false;
  return true;
}

TEST(SobolSampler, FirstPowerOfTwoPointsOfEverySlotAreNets) {
  for (uint32_t slot :
       {kPixelSlot, SlotsOfVertex(0).bsdf_dir, SlotsOfVertex(kPathVertexBudget - 1).light_point, 57u})
    for (uint32_t pixel : {0u, 1u, 12345u})
      for (int m = 0; m <= 10; ++m)
        EXPECT_TRUE(IsNet(PixelPoints(SamplerKind::kSobol, 42, pixel, slot, 1u << m), m))
            << "slot " << slot << " pixel " << pixel << " m " << m;
}

TEST(SobolSampler, AlignedBlocksLaterInTheSequenceAreNetsToo) {
  // Samples [a·2^m, (a+1)·2^m): what a task with a sample range sees, and the index shuffle's
  // block property (Burley 2020, §4).
  for (int m : {2, 5, 8})
    for (uint32_t a : {1u, 3u, 10u}) {
      std::vector<Sample2> p;
      for (uint32_t i = a << m; i < (a + 1) << m; ++i)
        p.push_back(Sampler::ForPixelSample(SamplerKind::kSobol, 7, 99, i).Get2D(SlotsOfVertex(1).bsdf_dir));
      EXPECT_TRUE(IsNet(p, m)) << "m " << m << " block " << a;
    }
}

TEST(SobolSampler, SubIndicesOfOneSampleAreANetAndSoAreAllSamplesTogether) {
  // N = 16 shadow rays per shading point: ray j of sample i at index 16 i + j.
  constexpr uint32_t kRays = 16;
  std::vector<Sample2> all;
  for (uint32_t i = 0; i < 64; ++i) {
    Sampler s = Sampler::ForPixelSample(SamplerKind::kSobol, 3, 5, i);
    std::vector<Sample2> one;
    for (uint32_t j = 0; j < kRays; ++j) one.push_back(s.Get2D(SlotsOfVertex(0).light_point, j, kRays));
    EXPECT_TRUE(IsNet(one, 4)) << "sample " << i;
    all.insert(all.end(), one.begin(), one.end());
  }
  EXPECT_TRUE(IsNet(all, 10));
}

TEST(SobolSampler, SubIndexedNumbersComputedAsABatchEqualThePerRequestOnes) {
  // Number j of N of sample i sits at index N·i + j of the slot's sequence, and the pixel stream's
  // key does not depend on the sample: it must equal the single number of sample N·i + j. The
  // sampler computes a slot's N numbers in one pass on the first request (Sampler::Batch); asked
  // in any order, interleaved with other slots, as 1-D or 2-D, from a PixelStream or not, N up
  // to and past the batch size (33: the per-request path), the values must not change.
  for (uint32_t n : {2u, 3u, 16u, 32u, 33u})
    for (uint32_t i : {0u, 1u, 5u, 1000u}) {
      const PixelStream stream(SamplerKind::kSobol, 3, 5);
      Sampler a = Sampler::ForPixelSample(SamplerKind::kSobol, 3, 5, i);
      Sampler b = Sampler::ForPixelSample(stream, i);
      for (uint32_t slot : {SlotsOfVertex(0).light_point, SlotsOfVertex(1).gather_dir, 25u})
        for (uint32_t k = 0; k < n; ++k) {
          const uint32_t j = (k * 7 + 3) % n;  // a scrambled order (a permutation when 7 ∤ n)
          const Sample2 expected = Sampler::ForPixelSample(SamplerKind::kSobol, 3, 5, n * i + j).Get2D(slot);
          const Sample2 pa = a.Get2D(slot, j, n);
          const float ua = a.Get1D(SlotsOfVertex(0).light_stratum, j, n);  // another slot in between
          const Sample2 pb = b.Get2D(slot, j, n);
          ASSERT_EQ(pa.u, expected.u) << n << " " << i << " " << slot << " " << j;
          ASSERT_EQ(pa.v, expected.v) << n << " " << i << " " << slot << " " << j;
          ASSERT_EQ(pb.u, expected.u) << n << " " << i << " " << slot << " " << j;
          ASSERT_EQ(pb.v, expected.v) << n << " " << i << " " << slot << " " << j;
          ASSERT_EQ(b.Get1D(slot, j, n), expected.u) << n << " " << i << " " << slot << " " << j;
          ASSERT_EQ(ua, Sampler::ForPixelSample(SamplerKind::kSobol, 3, 5, n * i + j)
                            .Get1D(SlotsOfVertex(0).light_stratum));
        }
    }
}

TEST(SobolSampler, OneDimensionalSlotsAreStratified) {
  for (int m = 0; m <= 12; ++m) {
    std::vector<float> v;
    for (uint32_t i = 0; i < (1u << m); ++i)
      v.push_back(Sampler::ForPixelSample(SamplerKind::kSobol, 9, 77, i)
                      .Get1D(SlotsOfVertex(kPathVertexBudget - 1).roulette));
    EXPECT_TRUE(IsStratified1D(v, m)) << m;
  }
}

TEST(IndependentSampler, FailsTheStratificationTests) {
  // The same checks on the independent sampler: with 2^m uniform random points, the chance that
  // all 2^m cells of even one partition are filled once is (2^m)!/(2^m)^(2^m) (m = 6: 1e-27).
  int nets = 0, stratified = 0;
  for (uint32_t pixel = 0; pixel < 20; ++pixel) {
    nets += IsNet(PixelPoints(SamplerKind::kIndependent, 42, pixel, kPixelSlot, 64), 6);
    std::vector<float> v;
    for (uint32_t i = 0; i < 64; ++i)
      v.push_back(Sampler::ForPixelSample(SamplerKind::kIndependent, 9, pixel, i).Get1D(kPixelSlot));
    stratified += IsStratified1D(v, 6);
  }
  EXPECT_EQ(nets, 0);
  EXPECT_EQ(stratified, 0);
}

TEST(SobolSampler, SlotsBeyondTheBudgetAndSubIndicesBeyondNFallBackToTheIndependentStream) {
  EXPECT_EQ(SlotsOfVertex(kPathVertexBudget).bsdf_dir, kIndependentSlot);
  EXPECT_EQ(SlotsOfPhotonBounce(kPhotonBounceBudget).lobe, kIndependentSlot);
  // Fallback numbers are the sample's PCG stream, in call order.
  Sampler s = Sampler::ForPixelSample(SamplerKind::kSobol, 1, 2, 3);
  Rng expected = Rng::ForKey(HashKey(1, 2, 3));
  EXPECT_EQ(s.Get1D(kIndependentSlot), expected.Uniform());
  EXPECT_EQ(s.Get1D(5, /*j=*/4, /*subs=*/4), expected.Uniform());
  // The independent sampler is exactly the old per-sample stream, whatever the slot.
  Sampler ind = Sampler::ForPixelSample(SamplerKind::kIndependent, 1, 2, 3);
  Rng old = Rng::ForKey(HashKey(1, 2, 3));
  const Sample2 p = ind.Get2D(kPixelSlot);
  EXPECT_EQ(p.u, old.Uniform());
  EXPECT_EQ(p.v, old.Uniform());
  EXPECT_EQ(ind.Get1D(17), old.Uniform());
}

TEST(SobolSampler, ValuesDependOnlyOnKeyIndexAndSlotNotOnCallOrder) {
  Sampler a = Sampler::ForPixelSample(SamplerKind::kSobol, 5, 6, 7);
  Sampler b = Sampler::ForPixelSample(SamplerKind::kSobol, 5, 6, 7);
  const Sample2 a1 = a.Get2D(3), a2 = a.Get2D(12);
  const float a3 = a.Get1D(4, 2, 8);
  const float b3 = b.Get1D(4, 2, 8);
  const Sample2 b2 = b.Get2D(12), b1 = b.Get2D(3);
  EXPECT_EQ(a1.u, b1.u);
  EXPECT_EQ(a1.v, b1.v);
  EXPECT_EQ(a2.u, b2.u);
  EXPECT_EQ(a3, b3);
  EXPECT_EQ(a.Get2D(3).u, a1.u);  // asking again gives the same number
}

double Correlation(const std::vector<double>& a, const std::vector<double>& b) {
  double ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i], mb += b[i];
  ma /= double(a.size());
  mb /= double(b.size());
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

// The largest deviation of a k x k joint histogram of the pairs from its uniform count.
double MaxCellDeviation(const std::vector<std::pair<float, float>>& pairs, int k) {
  std::vector<double> count(size_t(k * k), 0);
  for (const auto& [x, y] : pairs) count[size_t(int(x * k) * k + int(y * k))] += 1;
  const double expected = double(pairs.size()) / (k * k);
  double worst = 0;
  for (double c : count) worst = std::max(worst, std::abs(c - expected));
  return worst;
}

TEST(SobolSampler, DifferentSlotsOfOneStreamAreNotCorrelated) {
  // Without the index shuffle every slot's first coordinate would be the same van der Corput
  // sequence under another scramble: the first digits of two slots would agree (or disagree) in
  // every sample, and the 4 x 4 histogram of (slot a, slot b) would hold 4 full and 12 empty
  // cells. With it, 4096 samples fill all 16 cells with 256 ± 20 % (iid points: ±3.3 sigma), and
  // the values' correlation is that of independent ones.
  for (uint32_t a = 0; a < 8; ++a)
    for (uint32_t b : {a + 1, a + 9}) {
      std::vector<std::pair<float, float>> pairs;
      std::vector<double> xa, xb;
      for (uint32_t i = 0; i < 4096; ++i) {
        Sampler s = Sampler::ForPixelSample(SamplerKind::kSobol, 11, 3 + a, i);
        pairs.push_back({s.Get1D(a), s.Get1D(b)});
        xa.push_back(pairs.back().first);
        xb.push_back(pairs.back().second);
      }
      EXPECT_LT(MaxCellDeviation(pairs, 4), 0.2 * 256) << "slots " << a << ", " << b;
      EXPECT_LT(std::abs(Correlation(xa, xb)), 4.0 / 64) << "slots " << a << ", " << b;  // 4 sigma
    }
  // The check fails without the shuffle: two Owen scrambles of the same van der Corput points.
  std::vector<std::pair<float, float>> unshuffled;
  for (uint32_t i = 0; i < 4096; ++i)
    unshuffled.push_back({sobol::ToFloat(sobol::OwenScramble(sobol::VanDerCorput(i), 1234)),
                          sobol::ToFloat(sobol::OwenScramble(sobol::VanDerCorput(i), 98765))});
  EXPECT_GT(MaxCellDeviation(unshuffled, 4), 0.5 * 256);
}

TEST(SobolSampler, TwoPhotonMapsStreamsAreUncorrelated) {
  // Photon i of map A and photon i of map B: the values (4 x 4 histogram and correlation, 4096
  // photons, bounds as in DifferentSlotsOfOneStreamAreNotCorrelated) and
  // the integration errors of the two maps (400 map pairs, 64 photons each) are independent —
  // what keeps the maps of a job independent and the farm's noise estimate valid.
  for (uint32_t slot : {kPhotonPointSlot, SlotsOfPhotonBounce(1).direction}) {
    std::vector<std::pair<float, float>> pairs;
    std::vector<double> xa, xb;
    for (uint64_t i = 0; i < 4096; ++i) {
      pairs.push_back({Sampler::ForPhoton(SamplerKind::kSobol, 1001, i).Get2D(slot).u,
                       Sampler::ForPhoton(SamplerKind::kSobol, 1002, i).Get2D(slot).v});
      xa.push_back(pairs.back().first);
      xb.push_back(pairs.back().second);
    }
    EXPECT_LT(MaxCellDeviation(pairs, 4), 0.2 * 256) << "slot " << slot;
    EXPECT_LT(std::abs(Correlation(xa, xb)), 4.0 / 64) << "slot " << slot;
  }
  const auto f = [](const Sample2& p) { return std::exp(p.u) * std::sin(3.0 * p.v); };
  const double exact = (std::exp(1.0) - 1.0) * (1.0 - std::cos(3.0)) / 3.0;
  auto error_of = [&](uint64_t map_seed) {
    double sum = 0;
    for (uint64_t i = 0; i < 64; ++i) sum += f(Sampler::ForPhoton(SamplerKind::kSobol, map_seed, i).Get2D(1));
    return sum / 64 - exact;
  };
  std::vector<double> ea, eb;
  for (uint64_t k = 0; k < 400; ++k) {
    ea.push_back(error_of(2 * k + 1));
    eb.push_back(error_of(2 * k + 2));
  }
  // |r| of 400 independent pairs: standard deviation 0.05; 4 sigma.
  EXPECT_LT(std::abs(Correlation(ea, eb)), 0.2);
  // And the estimate is unbiased: the mean error over 800 maps is within 4 standard errors of 0.
  double mean = 0, var = 0;
  for (size_t k = 0; k < ea.size(); ++k) mean += ea[k] + eb[k];
  mean /= 800;
  for (size_t k = 0; k < ea.size(); ++k)
    var += (ea[k] - mean) * (ea[k] - mean) + (eb[k] - mean) * (eb[k] - mean);
  var /= 799;
  EXPECT_LT(std::abs(mean), 4 * std::sqrt(var / 800));
}

TEST(SobolSampler, EveryPointIsUniformOverKeys) {
  // Sample 5 of 65536 pixels: 64-bin histogram, chi-square with 63 dof < 120 (p ≈ 1e-5).
  for (uint32_t slot : {0u, 8u}) {
    std::vector<double> count(64, 0);
    for (uint32_t p = 0; p < 65536; ++p)
      count[size_t(Sampler::ForPixelSample(SamplerKind::kSobol, 3, p, 5).Get1D(slot) * 64)]++;
    double chi2 = 0;
    for (double c : count) chi2 += (c - 1024) * (c - 1024) / 1024;
    EXPECT_LT(chi2, 120.0) << slot;
  }
}

TEST(SobolSampler, ScrambleFlipsEachDigitByItsOwnCoinPerPrefix) {
  // A nested uniform scramble flips digit d of x by a fair coin chosen per prefix (the first
  // d-1 digits). Over 20000 seeds: digit d flips half the time, and the coins of two prefixes
  // that differ only in digit d-1 agree half the time (a random linear scramble or a digital
  // shift would make them always agree). 5 sigma = ±0.018.
  constexpr int kSeeds = 20000;
  for (int d = 1; d <= 16; ++d) {
    const uint32_t bit = 1u << (32 - d);
    const uint32_t x0 = 0, x1 = d > 1 ? bit << 1 : 0;  // differ in digit d-1
    int flips = 0, agree = 0;
    for (int s = 0; s < kSeeds; ++s) {
      const uint32_t seed = uint32_t(Mix64(uint64_t(s)));
      const bool f0 = (sobol::OwenScramble(x0, seed) ^ x0) & bit;
      const bool f1 = (sobol::OwenScramble(x1, seed) ^ x1) & bit;
      flips += f0;
      agree += f0 == f1;
    }
    EXPECT_NEAR(double(flips) / kSeeds, 0.5, 0.018) << "digit " << d;
    if (d > 1) {
      EXPECT_NEAR(double(agree) / kSeeds, 0.5, 0.018) << "digit " << d;
    }
  }
}

TEST(SobolSampler, IntegratesASmoothFunctionFarBetterThanIndependentNumbers) {
  // RMSE over 100 pixels of the 256-sample estimate of a smooth 2-D integral. Owen-scrambled
  // nets converge as N^-1.5 for smooth integrands (N^-0.5 for independent points): at N = 256
  // that is > 10x lower error.
  const auto f = [](const Sample2& p) { return std::exp(p.u) * std::sin(3.0 * p.v); };
  const double exact = (std::exp(1.0) - 1.0) * (1.0 - std::cos(3.0)) / 3.0;
  auto rmse = [&](SamplerKind kind) {
    double se = 0;
    for (uint32_t pixel = 0; pixel < 100; ++pixel) {
      double sum = 0;
      for (const Sample2& p : PixelPoints(kind, 8, pixel, 4, 256)) sum += f(p);
      se += (sum / 256 - exact) * (sum / 256 - exact);
    }
    return std::sqrt(se / 100);
  };
  const double sobol = rmse(SamplerKind::kSobol), independent = rmse(SamplerKind::kIndependent);
  EXPECT_LT(sobol * 10, independent) << sobol << " vs " << independent;
}

// Two samplers give the same value at every slot inside and beyond the precomputed ones, at a
// sub-index and at the independent fallback slot.
void ExpectSameValues(Sampler& a, Sampler& b) {
  for (uint32_t slot = 0; slot < sobol::kPixelSeedSlots + 5; ++slot) {
    EXPECT_EQ(a.Get1D(slot), b.Get1D(slot)) << slot;
    const Sample2 qa = a.Get2D(slot), qb = b.Get2D(slot);
    EXPECT_EQ(qa.u, qb.u) << slot;
    EXPECT_EQ(qa.v, qb.v) << slot;
    const Sample2 pa = a.Get2D(slot, 3, 8), pb = b.Get2D(slot, 3, 8);
    EXPECT_EQ(pa.u, pb.u) << slot;
    EXPECT_EQ(pa.v, pb.v) << slot;
  }
  EXPECT_EQ(a.Get1D(kIndependentSlot), b.Get1D(kIndependentSlot));
}

TEST(SobolSampler, PrecomputedPixelStreamGivesExactlyTheSameValues) {
  // The renderer's per-pixel PixelStream (seeds of the budget's slots computed once, every such
  // slot's point computed in one pass per sample) must not change a single value: every slot inside and
  // beyond the precomputed ones, sub-indices and the independent fallback stream, for both kinds.
  for (SamplerKind kind : {SamplerKind::kSobol, SamplerKind::kIndependent})
    for (uint32_t pixel : {0u, 77u, 65535u}) {
      const PixelStream stream(kind, 42, pixel);
      for (uint32_t sample : {0u, 1u, 5u, 1000u}) {
        Sampler a = Sampler::ForPixelSample(kind, 42, pixel, sample);
        Sampler b = Sampler::ForPixelSample(stream, sample);
        ExpectSameValues(a, b);
      }
    }
}

TEST(SobolSampler, PrecomputedPhotonStreamGivesExactlyTheSameValues) {
  // The photon tracer's per-map PhotonStream (the budget's slot seeds computed once per map) must
  // not change a single value of any photon: slots inside and beyond the precomputed ones,
  // sub-indices, the independent fallback, photon numbers past 2^32 (independent kind), both kinds.
  for (SamplerKind kind : {SamplerKind::kSobol, SamplerKind::kIndependent})
    for (uint64_t map_seed : {1ull, 42ull, 0x9e3779b97f4a7c15ull}) {
      const PhotonStream stream(kind, map_seed);
      for (uint64_t photon : {0ull, 1ull, 4095ull, 123457ull, 0xffffffffull, (1ull << 32) + 5}) {
        Sampler a = Sampler::ForPhoton(kind, map_seed, photon);
        Sampler b = Sampler::ForPhoton(stream, photon);
        ExpectSameValues(a, b);
      }
    }
}

TEST(SobolSampler, PhotonLanesGiveTheScalarPointsForManyPhotons) {
  // The photon lanes (sobol::kPhotonSlotOfLane: slots 0-7 of every photon in one vector pass) must
  // give exactly Point1D / Point2D of the scalar path for every photon, whatever the order of the
  // requests: 4096 photon numbers spread over [0, 2^32) and three map seeds. A lane holding
  // another slot's seeds, a 2-D slot in a lane without y, or a wrong bit reversal changes values.
  Rng pick(7, 11);
  EXPECT_FALSE(PhotonStream(SamplerKind::kSobol, 3).HasLanes(uint64_t(1) << 32));  // the independent fallback
  EXPECT_FALSE(PhotonStream(SamplerKind::kIndependent, 3).HasLanes(5));
  {
    // The independent kind: PhotonGet*D draw from the photon's stream in request order, as Get*D.
    const PhotonStream independent(SamplerKind::kIndependent, 3);
    Sampler a = Sampler::ForPhoton(independent, 12), b = Sampler::ForPhoton(independent, 12);
    for (uint32_t slot = 0; slot < 12; ++slot) {
      ASSERT_EQ(a.Get1D(slot), b.PhotonGet1D(slot)) << slot;
      const Sample2 qa = a.Get2D(slot), qb = b.PhotonGet2D(slot);
      ASSERT_EQ(qa.u, qb.u) << slot;
      ASSERT_EQ(qa.v, qb.v) << slot;
    }
  }
  for (uint64_t map_seed : {3ull, 77ull, 0x123456789abcdefull}) {
    const PhotonStream stream(SamplerKind::kSobol, map_seed);
    for (int n = 0; n < 4096; ++n) {
      const uint64_t photon = n < 64 ? uint64_t(n) : pick.NextU32();
      Sampler a = Sampler::ForPhoton(SamplerKind::kSobol, map_seed, photon);
      Sampler b = Sampler::ForPhoton(stream, photon);
      // The lanes computed ahead (the photon tracer's batches) and handed to ForPhoton.
      ASSERT_TRUE(stream.HasLanes(photon));
      PhotonLanes lanes;
      stream.Lanes(photon, &lanes);
      Sampler c = Sampler::ForPhoton(stream, photon, lanes);
      for (uint32_t k = 0; k < sobol::kPhotonEagerLanes; ++k) {
        const uint32_t slot = (n % 2 == 0) ? k : sobol::kPhotonEagerLanes - 1 - k;  // both orders
        ASSERT_EQ(a.Get1D(slot), b.Get1D(slot)) << photon << " " << slot;
        ASSERT_EQ(a.Get1D(slot), c.Get1D(slot)) << photon << " " << slot;
        const Sample2 qa = a.Get2D(slot), qb = b.Get2D(slot), qc = c.Get2D(slot);
        ASSERT_EQ(qa.u, qb.u) << photon << " " << slot;
        ASSERT_EQ(qa.v, qb.v) << photon << " " << slot;
        ASSERT_EQ(qa.u, qc.u) << photon << " " << slot;
        ASSERT_EQ(qa.v, qc.v) << photon << " " << slot;
      }
      // Beyond the lanes (later bounces' slots) the samplers agree too, and the photon walk's
      // forced-inline reads (PhotonGet1D/2D) give Get1D/Get2D's numbers.
      Sampler d = Sampler::ForPhoton(stream, photon, lanes);
      for (uint32_t slot = 0; slot < 30; ++slot) {
        const Sample2 qa = a.Get2D(slot), qc = c.Get2D(slot), qd = d.PhotonGet2D(slot);
        ASSERT_EQ(qa.u, qc.u) << photon << " " << slot;
        ASSERT_EQ(qa.v, qc.v) << photon << " " << slot;
        ASSERT_EQ(qa.u, qd.u) << photon << " " << slot;
        ASSERT_EQ(qa.v, qd.v) << photon << " " << slot;
        ASSERT_EQ(a.Get1D(slot), d.PhotonGet1D(slot)) << photon << " " << slot;
      }
    }
  }
}

#if defined(__SSSE3__) && defined(__SSE4_1__)
// The 4-lane hash and bit reversal of PointsOfSlots against the scalar ones, bit for bit, on
// 400k random words and seeds plus the edge words (0, all ones, single bits).
TEST(SobolSampler, VectorHashAndBitReversalEqualTheScalarOnes) {
  Rng rng(99, 1);
  std::vector<uint32_t> words = {0u, 0xffffffffu, 0x80000000u, 1u, 0x0f0f0f0fu, 0x12345678u};
  for (int i = 0; i < 400000; ++i) words.push_back(rng.NextU32());
  for (size_t i = 0; i + 4 <= words.size(); i += 4) {
    alignas(16) uint32_t in[4], seeds[4], reversed[4], hashed[4];
    for (int l = 0; l < 4; ++l) {
      in[l] = words[i + l];
      seeds[l] = words[(i + l * 7 + 1) % words.size()];
    }
    _mm_store_si128(reinterpret_cast<__m128i*>(reversed), sobol::ReverseBits4(sobol::Load4(in)));
    _mm_store_si128(reinterpret_cast<__m128i*>(hashed),
                    sobol::NestedHash4(sobol::Load4(in), sobol::Load4(seeds)));
    for (int l = 0; l < 4; ++l) {
      ASSERT_EQ(reversed[l], sobol::ReverseBits(in[l])) << in[l];
      ASSERT_EQ(hashed[l], sobol::NestedHash(in[l], seeds[l])) << in[l] << " " << seeds[l];
    }
  }
}
#endif

TEST(SobolSampler, PascalProductFromTheReversedIndexEqualsTheDirectOne) {
  // Point2D reads dimension 1 from the bit-reversed index (kPascalOfReversed): the same points.
  for (uint32_t i : {0u, 1u, 2u, 3u, 255u, 256u, 12345u, 0x80000000u, 0xdeadbeefu, 0xffffffffu}) {
    const uint32_t h = sobol::ReverseBits(i);
    const uint32_t via_reversed =
        sobol::kPascalOfReversed[0][h & 255] ^ sobol::kPascalOfReversed[1][(h >> 8) & 255] ^
        sobol::kPascalOfReversed[2][(h >> 16) & 255] ^ sobol::kPascalOfReversed[3][h >> 24];
    EXPECT_EQ(sobol::ReverseBits(via_reversed), sobol::Pascal(i)) << i;
  }
}

TEST(SamplerKind, NamesRoundTrip) {
  for (SamplerKind k : {SamplerKind::kSobol, SamplerKind::kIndependent}) {
    EXPECT_EQ(ParseSamplerKind(SamplerName(k)), k);
  }
  EXPECT_FALSE(ParseSamplerKind("halton"));
}

}  // namespace
}  // namespace pf
