// Tests of the 18-byte photon (Wald 1999, §2.2), the NearestPhotons heap and the PhotonMap
// contract shared by both implementations (kd-tree §2.3, grid §2.4), checked against brute
// force. Structure-specific invariants live in kdtree_test.cpp and grid_test.cpp.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

#include "common/core/rng.h"
#include "common/photon/brute_force.h"
#include "common/photon/grid.h"
#include "common/photon/kdtree.h"
#include "common/photon/photon.h"
#include "common/photon/photon_map.h"
#include "common/photon/photon_map_factory.h"

namespace pf {
namespace {

// ---------------------------------------------------------------------------------------
// Photon layout

TEST(PhotonTest, IsEighteenTriviallyCopyableBytes) {
  EXPECT_EQ(sizeof(Photon), 18u);
  EXPECT_TRUE(std::is_trivially_copyable_v<Photon>);
  std::vector<Photon> v(10);
  EXPECT_EQ(reinterpret_cast<const char*>(&v[1]) - reinterpret_cast<const char*>(&v[0]), 18);
}

// ---------------------------------------------------------------------------------------
// Direction: θ/φ bytes and lookup tables

double AngleBetween(const Vec3d& a, const Vec3d& b) {
  // atan2(|a×b|, a·b) is accurate for small angles, unlike acos.
  return std::atan2(Length(Cross(a, b)), Dot(a, b));
}

Vec3 RandomDirection(Rng& rng) {
  const float z = 1.0f - 2.0f * rng.Uniform();
  const float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  const float phi = kTwoPi * rng.Uniform();
  return {r * std::cos(phi), r * std::sin(phi), z};
}

TEST(PhotonTest, DirectionTablesMatchLibm) {
  const auto& t = photon_detail::kDirectionTables;
  for (int i = 0; i < 256; ++i) {
    EXPECT_NEAR(t.cos_theta[i], std::cos(i * std::numbers::pi / 255.0), 1e-7) << i;
    EXPECT_NEAR(t.sin_theta[i], std::sin(i * std::numbers::pi / 255.0), 1e-7) << i;
    EXPECT_NEAR(t.cos_phi[i], std::cos(i * 2.0 * std::numbers::pi / 256.0), 1e-7) << i;
    EXPECT_NEAR(t.sin_phi[i], std::sin(i * 2.0 * std::numbers::pi / 256.0), 1e-7) << i;
  }
}

// The stated bound: |Δθ| ≤ π/510 and |Δφ| ≤ π/256 (rounding to the nearest bin); by the
// haversine formula the angle between ω and its decoded form is then at most
// 2·asin(√(sin²(π/1020) + sin²(π/512))) ≈ 0.01373 rad ≈ 0.787°.
TEST(PhotonTest, DirectionErrorWithinStatedBound) {
  const double pi = std::numbers::pi;
  const double bound =
      2.0 * std::asin(std::sqrt(std::pow(std::sin(pi / 1020), 2) + std::pow(std::sin(pi / 512), 2)));
  EXPECT_NEAR(kMaxDirectionErrorRadians, bound, 1e-15);
  std::vector<Vec3> dirs = {{1, 0, 0},     {-1, 0, 0},     {0, 1, 0},       {0, -1, 0},
                            {0, 0, 1},     {0, 0, -1},     {-1, -1e-7f, 0}, {-1, 1e-7f, 0},
                            {1e-4f, 0, 1}, {0, 1e-4f, -1}, {1, 1, 1}};
  Rng rng(7, 1);
  for (int i = 0; i < 200000; ++i) dirs.push_back(RandomDirection(rng));
  double worst = 0.0;
  for (const Vec3& w : dirs) {
    const Vec3d exact = Normalize(Vec3d(w));
    const Vec3 decoded = DecodeDirection(EncodeDirection(w));
    EXPECT_NEAR(Length(decoded), 1.0f, 1e-6f);
    const double angle = AngleBetween(exact, Vec3d(decoded));
    worst = std::max(worst, angle);
    // 1e-6 rad of slack for the float decode tables.
    ASSERT_LE(angle, kMaxDirectionErrorRadians + 1e-6) << w.x << " " << w.y << " " << w.z;
  }
  // The bound is tight: random directions come close to it.
  EXPECT_GT(worst, 0.97 * kMaxDirectionErrorRadians);
}

TEST(PhotonTest, DirectionBinsFollowTheThesisFormula) {
  // theta = 255·acos(z)/π, phi = 256·atan2(y, x)/2π mod 256 (rounded).
  EXPECT_EQ(EncodeDirection({0, 0, 1}).theta, 0);
  EXPECT_EQ(EncodeDirection({0, 0, -1}).theta, 255);
  EXPECT_NEAR(EncodeDirection({1, 0, 0}).theta, 127.5, 0.5);  // the equator sits on a bin edge
  EXPECT_EQ(EncodeDirection({1, 0, 0}).phi, 0);
  EXPECT_EQ(EncodeDirection({0, 1, 0}).phi, 64);
  EXPECT_EQ(EncodeDirection({-1, 0, 0}).phi, 128);
  EXPECT_EQ(EncodeDirection({0, -1, 0}).phi, 192);
  EXPECT_EQ(EncodeDirection({1, -1e-6f, 0}).phi, 0);  // just below the seam wraps to 0
  // Not normalised: only the direction matters.
  EXPECT_EQ(EncodeDirection({0, 5, 0}).phi, 64);
  // Every non-polar bin centre round-trips exactly.
  for (int t = 1; t < 255; ++t) {
    for (int p = 0; p < 256; ++p) {
      const DirectionBytes d = EncodeDirection(DecodeDirection({uint8_t(t), uint8_t(p)}));
      ASSERT_EQ(d.theta, t);
      ASSERT_EQ(d.phi, p);
    }
  }
}

TEST(PhotonTest, DegenerateDirectionsEncodeAsPlusZ) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (const Vec3& w : {Vec3(0, 0, 0), Vec3(nan, 0, 0), Vec3(inf, 1, 0)}) {
    const DirectionBytes d = EncodeDirection(w);
    EXPECT_EQ(d.theta, 0);
    EXPECT_EQ(d.phi, 0);
  }
  // Huge but finite components are fine.
  EXPECT_EQ(EncodeDirection({0, 3e38f, 0}).phi, 64);
}

// ---------------------------------------------------------------------------------------
// Power: RGBE

// Checks the bounds stated in photon.h for a power whose largest channel is ≥ 2^-128.
void ExpectRgbeBounds(const Rgb& c) {
  const Rgb d = DecodeRgbe(EncodeRgbe(c));
  const double m = c.Max();
  const double decoded_max = d.Max();
  ASSERT_TRUE(d.IsFinite());
  for (int i = 0; i < 3; ++i) {
    // All arithmetic below is exact in double (float inputs, power-of-two scales).
    const double err = std::abs(double(d[i]) - double(c[i]));
    ASSERT_LE(err, decoded_max * 0x1p-8) << c[i];
    ASSERT_LE(err, m / 255.5) << c[i];
    if (c[i] == m) {
      ASSERT_LE(err, m * kMaxRgbeRelativeError) << c[i];
    }
    if (c[i] == 0.0f) {
      ASSERT_EQ(d[i], 0.0f);
    }
  }
}

TEST(PhotonTest, RgbeErrorWithinStatedBounds) {
  Rng rng(11, 2);
  for (int i = 0; i < 200000; ++i) {
    const float scale = std::ldexp(1.0f, int(rng.UniformInt(250)) - 127);  // 2^-127 .. 2^122
    Rgb c(rng.Uniform() * scale, rng.Uniform() * scale, rng.Uniform() * scale);
    if (i % 7 == 0) c.g = 0.0f;
    if (i % 11 == 0) c.b = c.r * 1e-6f;
    if (c.Max() < 0x1p-128f) continue;
    ExpectRgbeBounds(c);
  }
  // Mantissas that round up into the next binade (the "carry" case).
  for (float m : {0.999f, 0.99999f, 255.9f / 256.0f, 0.9981f * 0x1p-100f, 0.9991f * 0x1p100f}) {
    ExpectRgbeBounds({m, m * 0.3f, m * 0.00201f});
    ExpectRgbeBounds({m * 0.5f, m, 0.0f});
  }
  ExpectRgbeBounds({1.0f, 1.0f, 1.0f});
  ExpectRgbeBounds({std::numeric_limits<float>::min(), 0.0f, 0.0f});
}

TEST(PhotonTest, RgbeExactCases) {
  const RgbeBytes black = EncodeRgbe({0, 0, 0});
  EXPECT_EQ(black, (RgbeBytes{0, 0, 0, 0}));
  EXPECT_EQ(DecodeRgbe(black), Rgb(0.0f));
  // Powers of two and small integers are exact.
  EXPECT_EQ(DecodeRgbe(EncodeRgbe({1.0f, 0.5f, 0.25f})), Rgb(1.0f, 0.5f, 0.25f));
  EXPECT_EQ(DecodeRgbe(EncodeRgbe({200.0f, 3.0f, 0.0f})), Rgb(200.0f, 3.0f, 0.0f));
  // Every normalised byte pattern (max mantissa ≥ 128, E ≥ 1) is a fixed point.
  for (int e = 1; e < 256; e += 3) {
    for (int m = 128; m < 256; m += 5) {
      const RgbeBytes bytes{uint8_t(m), uint8_t(m / 3), 0, uint8_t(e)};
      ASSERT_EQ(EncodeRgbe(DecodeRgbe(bytes)), bytes) << e << " " << m;
    }
  }
}

TEST(PhotonTest, RgbeNeverProducesNanOrInf) {
  for (int e = 0; e < 256; ++e) {
    for (int m = 0; m < 256; ++m) {
      const Rgb d = DecodeRgbe({uint8_t(m), 255, uint8_t(255 - m), uint8_t(e)});
      ASSERT_TRUE(d.IsFinite());
      ASSERT_GE(d.Max(), 0.0f);
    }
  }
  const float inf = std::numeric_limits<float>::infinity();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float big = std::numeric_limits<float>::max();
  // Huge: clamped to the largest representable value, chromaticity kept.
  for (const Rgb& c : {Rgb(inf, inf, inf), Rgb(big, big, big), Rgb(inf, 1, 0), Rgb(3e38f, 0, 0)}) {
    const Rgb d = DecodeRgbe(EncodeRgbe(c));
    EXPECT_TRUE(d.IsFinite());
    EXPECT_EQ(d.Max(), kMaxRgbeValue);
  }
  const Rgb half = DecodeRgbe(EncodeRgbe({big, big * 0.5f, 0}));
  EXPECT_NEAR(half.g / half.r, 0.5, 0x1p-8);
  // Just below the clamp threshold rounds normally.
  ExpectRgbeBounds({255.4f * 0x1p119f, 1e30f, 0.0f});
  // NaN and negative channels are treated as zero.
  EXPECT_EQ(DecodeRgbe(EncodeRgbe({nan, 1.0f, -2.0f})), Rgb(0.0f, 1.0f, 0.0f));
  EXPECT_EQ(DecodeRgbe(EncodeRgbe({nan, nan, nan})), Rgb(0.0f));
  EXPECT_EQ(DecodeRgbe(EncodeRgbe({-1, -1, -1})), Rgb(0.0f));
}

TEST(PhotonTest, RgbeTinyPowersUnderflowGradually) {
  const float denorm_min = std::numeric_limits<float>::denorm_min();
  for (float v : {0x1p-129f, 0x1p-131f, 1e-40f, 0x1p-136f * 1.5f, 0x1p-140f, denorm_min}) {
    const Rgb c(v, v * 0.25f, 0.0f);
    const Rgb d = DecodeRgbe(EncodeRgbe(c));
    EXPECT_TRUE(d.IsFinite());
    for (int i = 0; i < 3; ++i) EXPECT_LE(std::abs(double(d[i]) - double(c[i])), 0x1p-136) << v;
  }
  EXPECT_EQ(EncodeRgbe({0x1p-140f, 0, 0}), (RgbeBytes{0, 0, 0, 0}));  // below 2^-136: black
}

TEST(PhotonTest, MakeRoundTrips) {
  const Photon p = Photon::Make({1.5f, -2.25f, 1e6f}, {0.3f, -0.4f, 0.866f}, {0.1f, 0.02f, 0.003f});
  EXPECT_EQ(p.Position(), Vec3(1.5f, -2.25f, 1e6f));
  EXPECT_LE(AngleBetween(Normalize(Vec3d(0.3, -0.4, 0.866)), Vec3d(p.Direction())),
            kMaxDirectionErrorRadians + 1e-6);
  const Rgb power = p.Power();
  EXPECT_NEAR(power.r, 0.1f, 0.1f / 256);
  EXPECT_NEAR(power.g, 0.02f, 0.1f / 256);
  EXPECT_NEAR(power.b, 0.003f, 0.1f / 256);
}

// ---------------------------------------------------------------------------------------
// NearestPhotons

TEST(NearestPhotonsTest, KeepsTheKSmallestAsAMaxHeap) {
  NearestPhotons heap;
  heap.Reset(10, std::numeric_limits<float>::infinity());
  EXPECT_EQ(heap.BoundSquared(), std::numeric_limits<float>::infinity());
  Rng rng(3, 3);
  std::vector<float> all;
  for (uint32_t i = 0; i < 1000; ++i) {
    const float d2 = rng.Uniform();
    all.push_back(d2);
    if (d2 < heap.BoundSquared()) heap.Insert(i, d2);
    for (std::size_t j = 1; j < heap.size(); ++j)
      ASSERT_LE(heap[j].distance2, heap[(j - 1) / 2].distance2);  // max-heap
    ASSERT_EQ(heap.MaxDistanceSquared(), heap[0].distance2);
  }
  ASSERT_TRUE(heap.full());
  EXPECT_EQ(heap.BoundSquared(), heap.MaxDistanceSquared());
  std::sort(all.begin(), all.end());
  heap.Sort();
  for (std::size_t j = 0; j < 10; ++j) EXPECT_EQ(heap[j].distance2, all[j]);
}

TEST(NearestPhotonsTest, RadiusAndDegenerateK) {
  NearestPhotons heap;
  heap.Reset(5, 2.0f);
  EXPECT_EQ(heap.BoundSquared(), 4.0f);
  EXPECT_EQ(heap.MaxDistanceSquared(), 0.0f);
  heap.Insert(0, 1.0f);
  EXPECT_EQ(heap.BoundSquared(), 4.0f);  // not full: the radius still bounds
  EXPECT_EQ(heap.MaxDistanceSquared(), 1.0f);
  heap.Reset(0, 1.0f);
  EXPECT_TRUE(heap.full());
  heap.Reset(-3, 1.0f);
  EXPECT_EQ(heap.k(), 0u);
  heap.Reset(3, -1.0f);
  EXPECT_EQ(heap.BoundSquared(), 0.0f);
  heap.Reset(3, std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(heap.BoundSquared(), 0.0f);
}

// ---------------------------------------------------------------------------------------
// The PhotonMap contract, for every implementation, against brute force.

struct MapVariant {
  std::string name;
  PhotonMapKind kind;
  PhotonMapOptions options;
};

void PrintTo(const MapVariant& v, std::ostream* os) {
  *os << v.name;
}

PhotonMapOptions Bucket(BucketSplit split, int leaf_size, bool allow_avx2) {
  PhotonMapOptions o;
  o.bucket.split = split;
  o.bucket.leaf_size = leaf_size;
  o.bucket.allow_avx2 = allow_avx2;
  return o;
}

std::vector<MapVariant> AllVariants() {
  PhotonMapOptions widest;
  widest.kd_split_rule = KdSplitRule::kWidestExtent;
  PhotonMapOptions plane_culling;  // the thesis's original culling test (§2.3.2)
  plane_culling.kd_culling = KdCulling::kPlaneDistance;
  PhotonMapOptions fine_grid;
  fine_grid.grid.photons_per_voxel = 2.0f;  // many voxels: long seed fills
  PhotonMapOptions coarse_grid;
  coarse_grid.grid.photons_per_voxel = 400.0f;
  return {
      {"KdLevelCycle", PhotonMapKind::kKdTree, {}},
      {"KdWidest", PhotonMapKind::kKdTree, widest},
      {"KdPlaneCulling", PhotonMapKind::kKdTree, plane_culling},
      {"Grid", PhotonMapKind::kGrid, {}},
      {"GridFine", PhotonMapKind::kGrid, fine_grid},
      {"GridCoarse", PhotonMapKind::kGrid, coarse_grid},
      {"BucketMedian", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMedian, 8, true)},
      {"BucketMidpoint", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMidpoint, 8, true)},
      {"BucketMidpointSse", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMidpoint, 8, false)},
      {"BucketMedianLeaf13Sse", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMedian, 13, false)},
      {"BucketMidpointLeaf1", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMidpoint, 1, true)},
      {"BucketMidpointLeaf64", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMidpoint, 64, true)},
      // The shipped default bucket size (BucketKdOptions), on both SIMD kernels.
      {"BucketMedianLeaf32", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMedian, 32, true)},
      {"BucketMidpointLeaf32Sse", PhotonMapKind::kBucketKdTree, Bucket(BucketSplit::kMidpoint, 32, false)}};
}

Photon MakeTestPhoton(const Vec3& p, Rng& rng) {
  return Photon::Make(p, RandomDirection(rng), Rgb(rng.Uniform(), rng.Uniform(), rng.Uniform()));
}

enum class Layout { kUniform, kClustered, kPlanar, kDuplicates, kLine };

std::vector<Photon> MakePhotons(Layout layout, std::size_t n, uint64_t seed) {
  Rng rng(seed, 17);
  std::vector<Photon> out;
  out.reserve(n);
  auto gauss = [&rng] {  // Box–Muller
    const float u = std::max(rng.Uniform(), 1e-7f), v = rng.Uniform();
    return std::sqrt(-2.0f * std::log(u)) * std::cos(kTwoPi * v);
  };
  std::vector<Vec3> centres;
  for (int i = 0; i < 6; ++i) centres.push_back({rng.Uniform(), rng.Uniform(), rng.Uniform()});
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 p;
    switch (layout) {
      case Layout::kUniform:
        p = {rng.Uniform(), rng.Uniform(), rng.Uniform()};
        break;
      case Layout::kClustered: {  // caustic-like: tight gaussian blobs over a sparse background
        if (rng.Uniform() < 0.1f) {
          p = {rng.Uniform(), rng.Uniform(), rng.Uniform()};
        } else {
          const Vec3& c = centres[rng.UniformInt(uint32_t(centres.size()))];
          const float sigma = 0.002f + 0.01f * float(&c - centres.data()) / 6.0f;
          p = c + Vec3(gauss(), gauss(), gauss()) * sigma;
        }
        break;
      }
      case Layout::kPlanar:  // all z equal (a floor)
        p = {rng.Uniform(), rng.Uniform(), 0.25f};
        break;
      case Layout::kDuplicates:  // many photons at identical positions
        p = centres[rng.UniformInt(3)];
        if (rng.Uniform() < 0.2f) p = {rng.Uniform(), rng.Uniform(), rng.Uniform()};
        break;
      case Layout::kLine:
        p = {0.5f, rng.Uniform(), 0.5f};
        break;
    }
    out.push_back(MakeTestPhoton(p, rng));
  }
  return out;
}

std::vector<Vec3> MakeQueries(std::span<const Photon> photons, std::size_t n, uint64_t seed) {
  Rng rng(seed, 29);
  std::vector<Vec3> q;
  for (std::size_t i = 0; i < n; ++i) {
    if (i % 4 == 0 && !photons.empty()) {
      q.push_back(photons[rng.UniformInt(uint32_t(photons.size()))].Position());  // on a photon
    } else {
      q.push_back(Vec3(rng.Uniform(), rng.Uniform(), rng.Uniform()) * 1.4f - Vec3(0.2f));
    }
  }
  // Far away on every side.
  for (const Vec3& far : {Vec3(50, 0.5f, 0.5f), Vec3(-50, 0.5f, 0.5f), Vec3(0.5f, 1e4f, 0.5f),
                          Vec3(0.5f, 0.5f, -1e6f), Vec3(-1e3f, 2e3f, -3e3f), Vec3(1e15f, 1e15f, 1e15f)})
    q.push_back(far);
  return q;
}

// The entries of a finished query against brute force's `expected`: each entry's distance is
// its photon's, only accepted photons, none twice, and the same distance multiset.
void ExpectEntriesMatch(const PhotonMap& map, const Vec3& x, NearestPhotons& heap,
                        const std::vector<NearestPhotons::Entry>& expected, const PhotonFilter* filter) {
  std::vector<uint32_t> seen;
  for (const auto& e : heap.entries()) {
    ASSERT_LT(e.index, map.size());
    ASSERT_EQ(e.distance2, DistanceSquared(map.photon(e.index), x));
    if (filter != nullptr) {
      ASSERT_TRUE(filter->Accept(map.photon(e.index), e.index));
    }
    seen.push_back(e.index);
  }
  std::sort(seen.begin(), seen.end());
  ASSERT_EQ(std::adjacent_find(seen.begin(), seen.end()), seen.end()) << "photon found twice";
  heap.Sort();
  for (std::size_t j = 0; j < expected.size(); ++j)
    ASSERT_EQ(heap[j].distance2, expected[j].distance2) << "rank " << j;
}

// Compares one query with brute force: same distance multiset, consistent entries.
void ExpectMatchesBruteForce(const PhotonMap& map, const Vec3& x, int k, float radius, NearestPhotons& heap,
                             const PhotonFilter* filter = nullptr) {
  map.Query(x, k, radius, heap, filter);
  const auto expected = BruteForceNearest(map.photons(), x, k, radius, filter);
  ASSERT_EQ(heap.size(), expected.size())
      << "x=" << x.x << "," << x.y << "," << x.z << " k=" << k << " r=" << radius;
  for (std::size_t j = 1; j < heap.size(); ++j) ASSERT_LE(heap[j].distance2, heap[(j - 1) / 2].distance2);
  ASSERT_NO_FATAL_FAILURE(ExpectEntriesMatch(map, x, heap, expected, filter));
}

class PhotonMapContractTest : public ::testing::TestWithParam<MapVariant> {
 protected:
  std::unique_ptr<PhotonMap> Build(std::span<const Photon> photons) const {
    auto map = MakePhotonMap(GetParam().kind, GetParam().options);
    map->AddPhotons(photons);
    map->PrepareForQuery();
    return map;
  }
};

TEST_P(PhotonMapContractTest, MatchesBruteForceOnAllLayouts) {
  const float inf = std::numeric_limits<float>::infinity();
  for (Layout layout :
       {Layout::kUniform, Layout::kClustered, Layout::kPlanar, Layout::kDuplicates, Layout::kLine}) {
    SCOPED_TRACE(int(layout));
    const auto photons = MakePhotons(layout, 6000, 100 + uint64_t(layout));
    const auto map = Build(photons);
    ASSERT_EQ(map->size(), photons.size());
    NearestPhotons heap;
    for (const Vec3& x : MakeQueries(map->photons(), 60, 5)) {
      for (int k : {1, 8, 50, 300}) {
        ASSERT_NO_FATAL_FAILURE(ExpectMatchesBruteForce(*map, x, k, inf, heap));
        // max_radius limits: a radius that holds fewer than k photons, and a tiny one.
        ASSERT_NO_FATAL_FAILURE(ExpectMatchesBruteForce(*map, x, k, 0.03f, heap));
        ASSERT_NO_FATAL_FAILURE(ExpectMatchesBruteForce(*map, x, k, 1e-4f, heap));
      }
    }
  }
}

// QueryWithHint is exact whatever the hint: too small (re-query), exactly the k-th distance
// (open ball: the k-th photon itself is outside, so it must re-query), just above, far above.
TEST_P(PhotonMapContractTest, QueryWithHintEqualsQueryForAnyHint) {
  const float inf = std::numeric_limits<float>::infinity();
  const auto photons = MakePhotons(Layout::kClustered, 6000, 31);
  const auto map = Build(photons);
  NearestPhotons heap, reference;
  int hits = 0, misses = 0;
  for (const Vec3& x : MakeQueries(map->photons(), 80, 13)) {
    for (int k : {1, 20, 100}) {
      for (float max_radius : {inf, 0.05f}) {
        map->Query(x, k, max_radius, reference);
        const float kth = std::sqrt(reference.MaxDistanceSquared());
        for (float hint : {0.0f, 1e-6f, 0.5f * kth, kth, std::nextafter(kth, inf), 1.2f * kth, 1e30f}) {
          const bool used = map->QueryWithHint(x, k, max_radius, hint, heap);
          const auto expected = BruteForceNearest(map->photons(), x, k, max_radius);
          ASSERT_EQ(heap.size(), expected.size()) << "hint " << hint << " k " << k;
          heap.Sort();
          for (std::size_t j = 0; j < expected.size(); ++j)
            ASSERT_EQ(heap[j].distance2, expected[j].distance2);
          // The hint sufficed iff the open ball of radius hint (< max_radius) holds k photons.
          const auto in_hint = BruteForceNearest(map->photons(), x, k, hint);
          const bool expect_used = hint > 0.0f && hint < max_radius && in_hint.size() == std::size_t(k);
          ASSERT_EQ(used, expect_used) << "hint " << hint << " k " << k;
          (used ? hits : misses)++;
        }
      }
    }
  }
  EXPECT_GT(hits, 100);
  EXPECT_GT(misses, 100);
}

// The distances² of all photons accepted by `filter` around x, ascending (brute force).
std::vector<float> SortedDistances(const PhotonMap& map, const Vec3& x,
                                   const PhotonFilter* filter = nullptr) {
  std::vector<float> d2;
  for (std::size_t i = 0; i < map.size(); ++i)
    if (filter == nullptr || filter->Accept(map.photon(i), i))
      d2.push_back(DistanceSquared(map.photon(i), x));
  std::sort(d2.begin(), d2.end());
  return d2;
}

// A hint radius whose open ball (DistanceSquared < hint², as the maps test it) holds exactly
// the `count` nearest accepted photons, if one exists (not if the count-th and the next
// distance tie, or lie too close for a float radius between them).
std::optional<float> HintHolding(const std::vector<float>& sorted_d2, std::size_t count) {
  if (count > sorted_d2.size()) return std::nullopt;
  const float inner = count == 0 ? 0.0f : std::sqrt(sorted_d2[count - 1]);
  const float outer = count < sorted_d2.size() ? std::sqrt(sorted_d2[count]) : 2.0f * inner + 1.0f;
  float hint = 0.5f * (inner + outer);
  const auto holds = [&](float h) {
    const auto inside = std::lower_bound(sorted_d2.begin(), sorted_d2.end(), h * h) - sorted_d2.begin();
    return h > 0.0f && std::size_t(inside) == count;
  };
  for (int step = 0; step < 8 && !holds(hint); ++step) hint = std::nextafter(hint, outer);
  if (!holds(hint)) return std::nullopt;
  return hint;
}

// Checks a QueryWithHint result against brute force: the same distance multiset, the farthest
// entry first (the renderer sums all but entries()[0]), only accepted photons, none twice.
void ExpectHintedMatchesBruteForce(const PhotonMap& map, const Vec3& x, int k, float max_radius, float hint,
                                   NearestPhotons& heap, const PhotonFilter* filter, bool expect_used) {
  const bool used = map.QueryWithHint(x, k, max_radius, hint, heap, filter);
  ASSERT_EQ(used, expect_used) << "hint " << hint << " k " << k << " max_radius " << max_radius;
  const auto expected = BruteForceNearest(map.photons(), x, k, max_radius, filter);
  ASSERT_EQ(heap.size(), expected.size()) << "hint " << hint << " k " << k;
  for (std::size_t j = 1; j < heap.size(); ++j) ASSERT_LE(heap[j].distance2, heap[0].distance2);
  if (!heap.empty()) {
    ASSERT_EQ(heap.MaxDistanceSquared(), expected.back().distance2);
  }
  ASSERT_NO_FATAL_FAILURE(ExpectEntriesMatch(map, x, heap, expected, filter));
}

// The hinted pass at its edges (the bucket tree answers it without a heap, from a flat buffer
// of the ball's photons, BallCollector::Finish): a ball holding exactly k photons (used),
// k − 1 (not used: the full query runs), every photon of the map (the buffer fills and is
// compacted many times), exactly the buffer's capacity and one more, and a max_radius below
// the hint (the hint is ignored).
TEST_P(PhotonMapContractTest, QueryWithHintAtTheBallsEdges) {
  const float inf = std::numeric_limits<float>::infinity();
  const auto photons = MakePhotons(Layout::kClustered, 3000, 41);
  const auto map = Build(photons);
  NearestPhotons heap;
  int exact_hints = 0;  // hints that held exactly the intended count (the others are skipped)
  for (const Vec3& x : MakeQueries(map->photons(), 40, 17)) {
    const auto d2 = SortedDistances(*map, x);
    for (int k : {1, 2, 7, 50, 200}) {
      SCOPED_TRACE(k);
      const std::size_t uk = std::size_t(k);
      const std::size_t capacity = BallCollector::Capacity(uk);
      ASSERT_GT(capacity, uk);
      auto try_count = [&](std::size_t count, bool expect_used) {
        if (const auto hint = HintHolding(d2, count)) {
          ++exact_hints;
          ExpectHintedMatchesBruteForce(*map, x, k, inf, *hint, heap, nullptr, expect_used);
        }
      };
      ASSERT_NO_FATAL_FAILURE(try_count(uk, true));
      ASSERT_NO_FATAL_FAILURE(try_count(uk - 1, false));
      for (std::size_t count : {capacity - 1, capacity, capacity + 1, 2 * capacity + 3})
        ASSERT_NO_FATAL_FAILURE(try_count(count, true));
      // Every photon in the ball.
      ASSERT_NO_FATAL_FAILURE(ExpectHintedMatchesBruteForce(*map, x, k, inf, 1e30f, heap, nullptr, true));
      // max_radius below the hint: the hint is not used, the result is max_radius's.
      const float kth = std::sqrt(d2[uk - 1]);
      ASSERT_NO_FATAL_FAILURE(
          ExpectHintedMatchesBruteForce(*map, x, k, 0.5f * kth, 2.0f * kth, heap, nullptr, false));
      ASSERT_NO_FATAL_FAILURE(ExpectHintedMatchesBruteForce(*map, x, k, 2.0f * kth, 2.0f * kth, heap, nullptr,
                                                            false));  // hint == max_radius: not used
    }
  }
  EXPECT_GT(exact_hints, 600);  // of 40 × 5 × 6 tried
}

// A filter that rejects photons inside the hint ball: the ball must hold k *accepted* photons
// for the hint to suffice. Hints holding k accepted photons but many more photons in all, and
// hints holding k photons of which some are rejected (must re-query).
TEST_P(PhotonMapContractTest, QueryWithHintCountsOnlyAcceptedPhotons) {
  const float inf = std::numeric_limits<float>::infinity();
  const auto photons = MakePhotons(Layout::kClustered, 3000, 43);
  const auto map = Build(photons);
  const auto one_in_three = FunctionFilter([](const Photon&, std::size_t i) { return i % 3 == 0; });
  const auto from_above = FunctionFilter([](const Photon& p, std::size_t) { return p.Direction().z > 0.0f; });
  NearestPhotons heap;
  int exact_hints = 0;
  for (const PhotonFilter* filter :
       {static_cast<const PhotonFilter*>(&one_in_three), static_cast<const PhotonFilter*>(&from_above)}) {
    for (const Vec3& x : MakeQueries(map->photons(), 40, 19)) {
      const auto accepted = SortedDistances(*map, x, filter);
      const auto all = SortedDistances(*map, x);
      for (int k : {1, 10, 60}) {
        SCOPED_TRACE(k);
        const std::size_t uk = std::size_t(k);
        // Holds exactly k accepted photons (and about 3× or 2× as many photons in all).
        if (const auto hint = HintHolding(accepted, uk)) {
          ++exact_hints;
          ASSERT_NO_FATAL_FAILURE(ExpectHintedMatchesBruteForce(*map, x, k, inf, *hint, heap, filter, true));
        }
        // Holds k − 1 accepted photons: re-query.
        if (const auto hint = HintHolding(accepted, uk - 1)) {
          ASSERT_NO_FATAL_FAILURE(ExpectHintedMatchesBruteForce(*map, x, k, inf, *hint, heap, filter, false));
        }
        // Holds k photons in all, fewer accepted ones (unless the k nearest are all accepted).
        if (const auto hint = HintHolding(all, uk)) {
          const bool enough = accepted.size() >= uk && accepted[uk - 1] < *hint * *hint;
          ASSERT_NO_FATAL_FAILURE(
              ExpectHintedMatchesBruteForce(*map, x, k, inf, *hint, heap, filter, enough));
        }
      }
    }
  }
  EXPECT_GT(exact_hints, 150);  // of 2 × 40 × 3 tried
}

// BallCollector (the hinted pass without a heap) against a sort: the k nearest of the
// candidates, the farthest first, "fewer than k" reported as such; candidate counts below,
// at and above the buffer's capacity (which compacts it to the k nearest and lowers the
// bound). Coarse distances: many ties. Without a compaction the ties at the k-th distance
// keep the lower index; with one, a later candidate at the lowered bound is refused (the
// caller tests d2 < Bound()), so only the distances are compared then.
TEST(BallCollectorTest, KeepsTheKNearestCandidates) {
  Rng rng(5, 5);
  NearestPhotons heap;
  for (int k : {1, 3, 20, 100}) {
    const std::size_t uk = std::size_t(k);
    const std::size_t capacity = BallCollector::Capacity(uk);
    for (std::size_t count :
         {std::size_t(0), uk - 1, uk, uk + 1, capacity - 1, capacity, capacity + 1, 5 * capacity + 7}) {
      SCOPED_TRACE(testing::Message() << "k " << k << " count " << count);
      heap.Reset(k, std::sqrt(8.0f));  // bound² ≈ 8: every distance² below (0 … 7) is a candidate
      BallCollector ball(heap);
      const float initial_bound = ball.Bound();
      ASSERT_GT(initial_bound, 7.0f);
      std::vector<NearestPhotons::Entry> offered;
      bool compacted = false;
      for (std::size_t i = 0; i < count; ++i) {
        // Distinct indices in a scrambled order (1000003 is prime).
        const NearestPhotons::Entry e{uint32_t(i * 7919 % 1000003), float(rng.UniformInt(8))};
        offered.push_back(e);
        if (e.distance2 < ball.Bound()) ball.Add(e.index, e.distance2);
        compacted = compacted || ball.Bound() < initial_bound;
      }
      EXPECT_EQ(compacted, count >= capacity);
      const bool full = ball.Finish();
      ASSERT_EQ(full, count >= uk);
      if (!full) {
        EXPECT_EQ(heap.size(), 0u);
        continue;
      }
      ASSERT_EQ(heap.size(), uk);
      for (std::size_t j = 1; j < uk; ++j) ASSERT_LE(heap[j].distance2, heap[0].distance2);
      EXPECT_EQ(heap.BoundSquared(), heap.MaxDistanceSquared());
      std::sort(offered.begin(), offered.end(), [](const auto& a, const auto& b) {
        return a.distance2 < b.distance2 || (a.distance2 == b.distance2 && a.index < b.index);
      });
      heap.Sort();
      for (std::size_t j = 0; j < uk; ++j) {
        ASSERT_EQ(heap[j].distance2, offered[j].distance2) << j;
        if (!compacted) {
          ASSERT_EQ(heap[j].index, offered[j].index) << j;
        }
      }
    }
  }
}

// Degenerate bounds: a ball radius whose square is denormal or overflows to +inf (the bins'
// scale would be +inf or 0) must still select exactly.
TEST(BallCollectorTest, DenormalAndInfiniteBounds) {
  NearestPhotons heap;
  for (float radius : {1e-20f, 1e30f}) {
    SCOPED_TRACE(radius);
    heap.Reset(3, radius);
    ASSERT_GT(heap.BoundSquared(), 0.0f);
    BallCollector ball(heap);
    const float m = std::min(ball.Bound(), 1e38f);
    const std::vector<float> d2 = {0.0f, m * 0.5f, 0.0f, m * 0.25f, m * 0.75f};
    for (std::size_t i = 0; i < d2.size(); ++i) ball.Add(uint32_t(i), d2[i]);
    ASSERT_TRUE(ball.Finish());
    heap.Sort();
    EXPECT_EQ(heap[0].index, 0u);
    EXPECT_EQ(heap[1].index, 2u);
    EXPECT_EQ(heap[2].index, 3u);
  }
}

TEST_P(PhotonMapContractTest, InQueryFilterAlwaysFillsTheHeap) {
  // §4.1, in-query variant: only accepted photons enter the heap, so k are found whenever
  // k accepted photons exist. Here: "arrives from above" (direction z > 0), about half.
  const auto photons = MakePhotons(Layout::kClustered, 5000, 7);
  const auto map = Build(photons);
  const auto from_above = FunctionFilter([](const Photon& p, std::size_t) { return p.Direction().z > 0.0f; });
  const auto by_index = FunctionFilter([](const Photon&, std::size_t i) { return i % 3 == 0; });
  NearestPhotons heap;
  for (const Vec3& x : MakeQueries(map->photons(), 40, 8)) {
    for (int k : {1, 20, 100}) {
      ASSERT_NO_FATAL_FAILURE(
          ExpectMatchesBruteForce(*map, x, k, std::numeric_limits<float>::infinity(), heap, &from_above));
      EXPECT_EQ(heap.size(), std::size_t(k));
      ASSERT_NO_FATAL_FAILURE(ExpectMatchesBruteForce(*map, x, k, 0.05f, heap, &by_index));
    }
  }
}

TEST_P(PhotonMapContractTest, TinyMaps) {
  const float inf = std::numeric_limits<float>::infinity();
  NearestPhotons heap;
  // N = 0.
  {
    const auto map = Build({});
    map->Query({0, 0, 0}, 10, inf, heap);
    EXPECT_EQ(heap.size(), 0u);
    EXPECT_EQ(map->size(), 0u);
    map->QueryWithHint({0, 0, 0}, 10, inf, 0.5f, heap);
    EXPECT_EQ(heap.size(), 0u);
  }
  // N = 1 .. 40, N < k and N ≥ k, including every small tree shape; hinted queries (a ball
  // holding fewer than k, about k, or all photons) give the same distances as plain ones.
  NearestPhotons hinted;
  auto sorted_distances = [](NearestPhotons& h) {
    std::vector<float> d;
    for (const auto& e : h.entries()) d.push_back(e.distance2);
    std::sort(d.begin(), d.end());
    return d;
  };
  for (std::size_t n = 1; n <= 40; ++n) {
    const auto photons = MakePhotons(Layout::kUniform, n, 1000 + n);
    const auto map = Build(photons);
    for (const Vec3& x : MakeQueries(map->photons(), 12, n)) {
      for (int k : {1, 3, 7, 50}) {
        ASSERT_NO_FATAL_FAILURE(ExpectMatchesBruteForce(*map, x, k, inf, heap));
        map->Query(x, k, inf, heap);
        for (float hint : {0.05f, 0.3f, 10.0f}) {
          map->QueryWithHint(x, k, inf, hint, hinted);
          ASSERT_EQ(sorted_distances(hinted), sorted_distances(heap))
              << "n " << n << " k " << k << " hint " << hint;
          ASSERT_EQ(hinted.MaxDistanceSquared(), heap.MaxDistanceSquared());
        }
      }
    }
  }
  // One photon, repeated: every distance ties.
  const std::vector<Photon> same(100, Photon::Make({1, 2, 3}, {0, 0, 1}, Rgb(1)));
  const auto map = Build(same);
  map->Query({1, 2, 3.5f}, 10, inf, heap);
  ASSERT_EQ(heap.size(), 10u);
  for (const auto& e : heap.entries()) EXPECT_EQ(e.distance2, 0.25f);
}

TEST_P(PhotonMapContractTest, DegenerateQueries) {
  const auto map = Build(MakePhotons(Layout::kUniform, 1000, 3));
  NearestPhotons heap;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  map->Query({nan, 0, 0}, 10, 1.0f, heap);
  EXPECT_EQ(heap.size(), 0u);
  map->QueryWithHint({nan, 0, 0}, 10, 1.0f, 0.1f, heap);
  EXPECT_EQ(heap.size(), 0u);
  map->QueryWithHint({0.5f, 0.5f, 0.5f}, 10, 1.0f, std::numeric_limits<float>::infinity(), heap);
  EXPECT_EQ(heap.size(), 10u);
  map->QueryWithHint({0.5f, 0.5f, 0.5f}, 10, 1.0f, nan, heap);
  EXPECT_EQ(heap.size(), 10u);
  map->Query({0.5f, 0.5f, 0.5f}, 0, 1.0f, heap);
  EXPECT_EQ(heap.size(), 0u);
  map->Query({0.5f, 0.5f, 0.5f}, 10, 0.0f, heap);
  EXPECT_EQ(heap.size(), 0u);
  map->Query({0.5f, 0.5f, 0.5f}, 10, -1.0f, heap);
  EXPECT_EQ(heap.size(), 0u);
  // Far outside with a radius that does not reach the photons.
  map->Query({10, 10, 10}, 10, 5.0f, heap);
  EXPECT_EQ(heap.size(), 0u);
}

TEST_P(PhotonMapContractTest, LifecycleAndErrors) {
  auto map = MakePhotonMap(GetParam().kind, GetParam().options);
  NearestPhotons heap;
  map->AddPhoton({0, 0, 0}, {0, 0, 1}, Rgb(1));
  EXPECT_THROW(map->Query({0, 0, 0}, 1, 1.0f, heap), std::logic_error);
  map->PrepareForQuery();
  map->Query({0, 0, 0}, 1, 1.0f, heap);
  EXPECT_EQ(heap.size(), 1u);
  // Adding after the build un-prepares; re-preparing rebuilds from the current order.
  Rng rng(1, 1);
  for (const Photon& p : MakePhotons(Layout::kUniform, 500, 9)) map->AddPhoton(p);
  EXPECT_FALSE(map->prepared());
  EXPECT_THROW(map->Query({0, 0, 0}, 1, 1.0f, heap), std::logic_error);
  map->PrepareForQuery();
  for (const Vec3& x : MakeQueries(map->photons(), 20, 2))
    ASSERT_NO_FATAL_FAILURE(
        ExpectMatchesBruteForce(*map, x, 10, std::numeric_limits<float>::infinity(), heap));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(map->AddPhoton({nan, 0, 0}, {0, 0, 1}, Rgb(1)), std::invalid_argument);
  EXPECT_GE(map->MemoryBytes(), map->size() * sizeof(Photon));
}

TEST_P(PhotonMapContractTest, ConcurrentQueriesAgreeWithSequential) {
  const auto map = Build(MakePhotons(Layout::kClustered, 20000, 21));
  const auto queries = MakeQueries(map->photons(), 400, 22);
  // Plain and hinted queries (the hinted pass keeps its ball buffer in the per-thread
  // NearestPhotons: no state may leak between threads or queries).
  auto run = [&](std::size_t begin, std::size_t step, std::vector<float>& out) {
    NearestPhotons heap;  // one per thread
    for (std::size_t i = begin; i < queries.size(); i += step) {
      map->Query(queries[i], 30, 0.2f, heap);
      out[2 * i] = heap.MaxDistanceSquared() + float(heap.size());
      map->QueryWithHint(queries[i], 30, 0.2f, 0.03f + 0.0001f * float(i), heap);
      float sum = 0.0f;
      for (const auto& e : heap.entries()) sum += e.distance2;
      out[2 * i + 1] = sum + float(heap.size());
    }
  };
  std::vector<float> sequential(2 * queries.size()), parallel(2 * queries.size());
  run(0, 1, sequential);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < 4; ++t) threads.emplace_back(run, t, 4, std::ref(parallel));
  for (auto& t : threads) t.join();
  EXPECT_EQ(sequential, parallel);
}

INSTANTIATE_TEST_SUITE_P(AllPhotonMaps, PhotonMapContractTest, ::testing::ValuesIn(AllVariants()),
                         [](const auto& info) { return info.param.name; });

}  // namespace
}  // namespace pf

namespace pf {
namespace {

// PrepareForQuery(&original_index) must report the permutation of every structure exactly and
// leave the photons' powers intact (attributes outside the 18 bytes follow it, §4.1.1/§4.2.3).
TEST(PhotonMapPermutation, ReportsInsertionIndexAndKeepsPower) {
  for (PhotonMapKind kind : {PhotonMapKind::kKdTree, PhotonMapKind::kGrid, PhotonMapKind::kBucketKdTree}) {
    auto map = MakePhotonMap(kind);
    std::vector<Photon> inserted;
    Rng rng(9, 3);
    for (int i = 0; i < 5000; ++i) {
      const Vec3 p(rng.Uniform(), rng.Uniform() * 0.01f, rng.Uniform());
      const Photon ph = Photon::Make(p, Vec3(0, 1, 0), Rgb(rng.Uniform(), rng.Uniform(), 0.5f + i));
      inserted.push_back(ph);
      map->AddPhoton(ph);
    }
    std::vector<uint32_t> original;
    map->PrepareForQuery(&original);
    ASSERT_EQ(original.size(), inserted.size());
    std::vector<bool> seen(inserted.size(), false);
    for (size_t i = 0; i < original.size(); ++i) {
      ASSERT_LT(original[i], inserted.size());
      ASSERT_FALSE(seen[original[i]]);
      seen[original[i]] = true;
      ASSERT_EQ(std::memcmp(&map->photon(i), &inserted[original[i]], sizeof(Photon)), 0) << i;
    }
  }
}

}  // namespace
}  // namespace pf
