// The left-balanced kd-tree of Wald 1999, §2.3: the in-place BuildTree must leave a complete
// tree in the photon array that satisfies the kd-condition at every node, for both split
// rules and for awkward inputs (planar, duplicates, collinear, every small size). Queries are
// compared with brute force here for large trees; photon_test.cpp runs the shared contract.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "common/core/rng.h"
#include "common/photon/brute_force.h"
#include "common/photon/kdtree.h"

namespace pf {
namespace {

enum class Shape { kUniform, kClustered, kPlanar, kDuplicates, kLineY };

std::vector<Photon> Photons(Shape shape, std::size_t n, uint64_t seed) {
  Rng rng(seed, 5);
  std::vector<Photon> out;
  for (std::size_t i = 0; i < n; ++i) {
    Vec3 p{rng.Uniform(), rng.Uniform(), rng.Uniform()};
    switch (shape) {
      case Shape::kUniform:
        break;
      case Shape::kClustered:  // two tight blobs and a sparse background
        if (i % 10 != 0) p = Vec3(0.3f + 0.3f * float(i % 2)) + (p - Vec3(0.5f)) * 0.004f;
        break;
      case Shape::kPlanar:
        p.z = 0.75f;
        break;
      case Shape::kDuplicates:
        p = Vec3(float(rng.UniformInt(4)) * 0.25f);
        break;
      case Shape::kLineY:
        p.x = p.z = 0.5f;
        break;
    }
    out.push_back(Photon::Make(p, {0, 0, 1}, Rgb(float(i % 97) + 1.0f)));
  }
  return out;
}

KdTree BuildTree(const std::vector<Photon>& photons, KdSplitRule rule) {
  KdTree tree(rule);
  tree.AddPhotons(photons);
  tree.PrepareForQuery();
  return tree;
}

// Checks the kd-condition (§2.3, eq. 2.7) at every node in O(N): descending, each node
// narrows the interval its subtrees must lie in on its split axis; every photon must lie in
// the intervals of all its ancestors.
void CheckKdCondition(const KdTree& tree) {
  const std::size_t n = tree.size();
  struct Item {
    std::size_t node;
    std::array<float, 3> lo, hi;
  };
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<Item> stack = {{1, {-inf, -inf, -inf}, {inf, inf, inf}}};
  while (!stack.empty()) {
    const Item item = stack.back();
    stack.pop_back();
    if (item.node > n) continue;
    const Photon& p = tree.photon(item.node - 1);
    for (int a = 0; a < 3; ++a) {
      ASSERT_GE(p.position[a], item.lo[a]) << "node " << item.node << " axis " << a;
      ASSERT_LE(p.position[a], item.hi[a]) << "node " << item.node << " axis " << a;
    }
    const int axis = tree.SplitAxis(item.node);
    ASSERT_GE(axis, 0);
    ASSERT_LE(axis, 2);
    Item left = item, right = item;
    left.node = 2 * item.node;
    left.hi[axis] = p.position[axis];
    right.node = 2 * item.node + 1;
    right.lo[axis] = p.position[axis];
    stack.push_back(left);
    stack.push_back(right);
  }
}

// Size, height and perfection of the subtree under `node` in an implicit tree of n nodes.
struct SubtreeInfo {
  std::size_t size;
  int height;
  bool perfect;
};
SubtreeInfo Info(std::size_t node, std::size_t n) {
  if (node > n) return {0, 0, true};
  const SubtreeInfo l = Info(2 * node, n), r = Info(2 * node + 1, n);
  return {l.size + r.size + 1, std::max(l.height, r.height) + 1,
          l.perfect && r.perfect && l.height == r.height};
}
// A binary tree is complete ("all levels filled except the last, which is filled from left
// to right", §2.3) iff at every node either both subtrees have equal height and the left
// one is perfect, or the left one is one taller and the right one is perfect.
void CheckLeftBalancedShape(std::size_t n) {
  for (std::size_t node = 1; node <= n; ++node) {
    const SubtreeInfo l = Info(2 * node, n), r = Info(2 * node + 1, n);
    if (l.height == r.height) {
      ASSERT_TRUE(l.perfect) << node;
    } else {
      ASSERT_EQ(l.height, r.height + 1) << node;
      ASSERT_TRUE(r.perfect) << node;
    }
  }
  if (n > 0) {
    ASSERT_EQ(Info(1, n).size, n);
    ASSERT_EQ(Info(1, n).height, std::bit_width(n));  // minimal height: ⌊log2 N⌋ + 1
  }
}

// The build only permutes the photons: same multiset of 18-byte records.
void CheckPermutation(std::vector<Photon> before, const KdTree& tree) {
  std::vector<Photon> after(tree.photons().begin(), tree.photons().end());
  auto less = [](const Photon& a, const Photon& b) { return std::memcmp(&a, &b, sizeof(Photon)) < 0; };
  std::sort(before.begin(), before.end(), less);
  std::sort(after.begin(), after.end(), less);
  ASSERT_EQ(before.size(), after.size());
  ASSERT_EQ(std::memcmp(before.data(), after.data(), before.size() * sizeof(Photon)), 0);
}

// Trees of every size in [first, last] (uniform, planar and duplicate photons, both split
// rules) satisfy the kd-condition and hold a permutation of their input.
void CheckTreesOfSizes(std::size_t first, std::size_t last) {
  for (KdSplitRule rule : {KdSplitRule::kLevelCycle, KdSplitRule::kWidestExtent}) {
    for (Shape shape : {Shape::kUniform, Shape::kPlanar, Shape::kDuplicates}) {
      for (std::size_t n = first; n <= last; ++n) {
        SCOPED_TRACE(::testing::Message() << "rule " << int(rule) << " shape " << int(shape) << " n " << n);
        const auto photons = Photons(shape, n, n);
        const KdTree tree = BuildTree(photons, rule);
        ASSERT_NO_FATAL_FAILURE(CheckKdCondition(tree));
        ASSERT_NO_FATAL_FAILURE(CheckPermutation(photons, tree));
      }
    }
  }
}

TEST(KdTreeTest, KdConditionAndShapeForEverySmallSize) {
  ASSERT_NO_FATAL_FAILURE(CheckTreesOfSizes(1, 80));
  for (std::size_t n = 0; n <= 300; ++n) ASSERT_NO_FATAL_FAILURE(CheckLeftBalancedShape(n));
}

// Subtrees of more than 1024 photons are partitioned in place over the level-order sequence
// (kdtree.cpp); just above that size the sequence starts with runs of 1, 2, 4, ... nodes, so
// every run boundary is crossed by the partition cursors.
TEST(KdTreeTest, KdConditionJustAboveTheSmallSubtreeSize) {
  ASSERT_NO_FATAL_FAILURE(CheckTreesOfSizes(1020, 1120));
}

TEST(KdTreeTest, KdConditionForLargeAwkwardInputs) {
  for (KdSplitRule rule : {KdSplitRule::kLevelCycle, KdSplitRule::kWidestExtent}) {
    for (Shape shape :
         {Shape::kUniform, Shape::kClustered, Shape::kPlanar, Shape::kDuplicates, Shape::kLineY}) {
      for (std::size_t n : {4095u, 4096u, 4097u, 50000u}) {
        SCOPED_TRACE(::testing::Message() << "rule " << int(rule) << " shape " << int(shape) << " n " << n);
        const auto photons = Photons(shape, n, 40 + n);
        const KdTree tree = BuildTree(photons, rule);
        ASSERT_NO_FATAL_FAILURE(CheckKdCondition(tree));
        ASSERT_NO_FATAL_FAILURE(CheckPermutation(photons, tree));
      }
    }
  }
}

TEST(KdTreeTest, SplitAxisRules) {
  // level % 3 (§2.3): depth of node i is ⌊log2 i⌋.
  const KdTree cycle = BuildTree(Photons(Shape::kUniform, 100, 1), KdSplitRule::kLevelCycle);
  EXPECT_EQ(cycle.SplitAxis(1), 0);
  EXPECT_EQ(cycle.SplitAxis(2), 1);
  EXPECT_EQ(cycle.SplitAxis(3), 1);
  EXPECT_EQ(cycle.SplitAxis(4), 2);
  EXPECT_EQ(cycle.SplitAxis(8), 0);
  EXPECT_EQ(cycle.SplitAxis(31), 1);
  // Widest extent (§2.3, footnote 2): a flat scene never splits along its flat axis...
  const std::size_t n = 5000;
  const KdTree flat = BuildTree(Photons(Shape::kPlanar, n, 2), KdSplitRule::kWidestExtent);
  for (std::size_t node = 1; 2 * node <= n; ++node) ASSERT_NE(flat.SplitAxis(node), 2) << node;
  // ...and a line along y splits along y everywhere.
  const KdTree line = BuildTree(Photons(Shape::kLineY, n, 3), KdSplitRule::kWidestExtent);
  for (std::size_t node = 1; 2 * node <= n; ++node) ASSERT_EQ(line.SplitAxis(node), 1) << node;
  // A box that is wide in x: the root splits x.
  std::vector<Photon> wide = Photons(Shape::kUniform, 1000, 4);
  for (Photon& p : wide) p.position[0] *= 10.0f;
  EXPECT_EQ(BuildTree(wide, KdSplitRule::kWidestExtent).SplitAxis(1), 0);
}

TEST(KdTreeTest, NoMemoryBeyondThePhotonArray) {
  const std::size_t n = 10001;
  const KdTree cycle = BuildTree(Photons(Shape::kUniform, n, 5), KdSplitRule::kLevelCycle);
  EXPECT_EQ(cycle.MemoryBytes(), n * sizeof(Photon));  // 18 bytes per photon, nothing else
  const KdTree widest = BuildTree(Photons(Shape::kUniform, n, 5), KdSplitRule::kWidestExtent);
  EXPECT_EQ(widest.MemoryBytes(), n * sizeof(Photon) + n / 4 + 1);  // + 2 bits per node
}

TEST(KdTreeTest, BuildIsDeterministic) {
  const auto photons = Photons(Shape::kClustered, 20000, 6);
  const KdTree a = BuildTree(photons, KdSplitRule::kWidestExtent);
  const KdTree b = BuildTree(photons, KdSplitRule::kWidestExtent);
  ASSERT_EQ(std::memcmp(a.photons().data(), b.photons().data(), photons.size() * sizeof(Photon)), 0);
}

// The tree's k nearest photons within `radius` of x have the squared distances, ascending, of
// those brute force finds.
void ExpectQueryMatchesBruteForce(const KdTree& tree, const Vec3& x, int k, float radius,
                                  NearestPhotons& heap) {
  tree.Query(x, k, radius, heap);
  const auto expected = BruteForceNearest(tree.photons(), x, k, radius);
  ASSERT_EQ(heap.size(), expected.size());
  heap.Sort();
  for (std::size_t j = 0; j < expected.size(); ++j) ASSERT_EQ(heap[j].distance2, expected[j].distance2);
}

TEST(KdTreeTest, LargeTreeMatchesBruteForce) {
  const float inf = std::numeric_limits<float>::infinity();
  for (KdSplitRule rule : {KdSplitRule::kLevelCycle, KdSplitRule::kWidestExtent}) {
    for (Shape shape : {Shape::kUniform, Shape::kClustered, Shape::kPlanar}) {
      KdTree tree(rule, shape == Shape::kClustered ? KdCulling::kPlaneDistance : KdCulling::kCellDistance);
      tree.AddPhotons(Photons(shape, 60000, 7));
      tree.PrepareForQuery();
      Rng rng(8, 8);
      NearestPhotons heap;
      for (int q = 0; q < 40; ++q) {
        Vec3 x{rng.Uniform(), rng.Uniform(), rng.Uniform()};
        if (q % 5 == 0) x = x * 40.0f - Vec3(20.0f);  // mostly far outside
        if (q % 7 == 0) x = tree.photon(rng.UniformInt(uint32_t(tree.size()))).Position();
        for (int k : {1, 50, 500}) {
          for (float radius : {inf, 0.02f}) {
            ASSERT_NO_FATAL_FAILURE(ExpectQueryMatchesBruteForce(tree, x, k, radius, heap));
          }
        }
      }
    }
  }
}

// The parallel build (subtrees of ≥ 32k photons balanced concurrently) must give exactly the
// serial array — and the same axis bits — for any thread count, and still be a valid
// left-balanced kd-tree whose queries match brute force. Sizes straddle the parallel threshold
// (2 × 32768) so that both the serial fallback and several parallel levels run, and the
// widest-extent rule exercises concurrent writes to shared bytes of the axis array.
TEST(KdTreeTest, ParallelBuildGivesTheSerialArrayForAnyThreadCount) {
  const float inf = std::numeric_limits<float>::infinity();
  for (KdSplitRule rule : {KdSplitRule::kLevelCycle, KdSplitRule::kWidestExtent}) {
    for (const auto& [shape, n] :
         {std::pair{Shape::kClustered, std::size_t(65535)}, std::pair{Shape::kUniform, std::size_t(300001)},
          std::pair{Shape::kPlanar, std::size_t(140000)},
          std::pair{Shape::kDuplicates, std::size_t(131072)}}) {
      const std::vector<Photon> photons = Photons(shape, n, 11);
      KdTree serial(rule);
      serial.AddPhotons(photons);
      serial.PrepareForQuery();
      for (int threads : {2, 3, 0}) {
        KdTree parallel(rule);
        parallel.AddPhotons(photons);
        parallel.set_build_threads(threads);
        parallel.PrepareForQuery();
        ASSERT_EQ(parallel.size(), n);
        ASSERT_EQ(std::memcmp(serial.photons().data(), parallel.photons().data(), n * sizeof(Photon)), 0)
            << "rule " << int(rule) << " shape " << int(shape) << " n " << n << " threads " << threads;
        for (std::size_t node = 1; node <= n / 2; ++node)
          ASSERT_EQ(serial.SplitAxis(node), parallel.SplitAxis(node)) << node;
      }
      KdTree tree(rule);
      tree.AddPhotons(photons);
      tree.set_build_threads(2);
      tree.PrepareForQuery();
      CheckKdCondition(tree);
      CheckPermutation(photons, tree);
      Rng rng(12, 12);
      NearestPhotons heap;
      for (int q = 0; q < 20; ++q) {
        const Vec3 x = q % 4 == 0 ? tree.photon(rng.UniformInt(uint32_t(n))).Position()
                                  : Vec3{rng.Uniform(), rng.Uniform(), rng.Uniform()};
        for (int k : {1, 100}) {
          ASSERT_NO_FATAL_FAILURE(ExpectQueryMatchesBruteForce(tree, x, k, inf, heap));
        }
      }
    }
  }
}

TEST(KdTreeTest, QueryWithStatsEqualsQueryAndCounts) {
  // The instrumented search (benchmarks) is the same search: same heap, bit for bit, and its
  // counters are consistent (every insert and every far-child visit follows a node visit).
  const float inf = std::numeric_limits<float>::infinity();
  for (KdSplitRule rule : {KdSplitRule::kLevelCycle, KdSplitRule::kWidestExtent}) {
    for (KdCulling culling : {KdCulling::kCellDistance, KdCulling::kPlaneDistance}) {
      KdTree tree(rule, culling);
      tree.AddPhotons(Photons(Shape::kClustered, 20000, 9));
      tree.PrepareForQuery();
      Rng rng(10, 10);
      NearestPhotons a, b;
      for (int q = 0; q < 30; ++q) {
        const Vec3 x{rng.Uniform(), rng.Uniform(), rng.Uniform()};
        for (int k : {1, 50, 300}) {
          tree.Query(x, k, inf, a);
          KdTree::SearchStats stats;
          tree.QueryWithStats(x, k, inf, b, &stats);
          ASSERT_EQ(a.size(), b.size());
          for (std::size_t j = 0; j < a.size(); ++j) {
            ASSERT_EQ(a[j].index, b[j].index);
            ASSERT_EQ(a[j].distance2, b[j].distance2);
          }
          EXPECT_GE(stats.nodes, std::size_t(k));
          EXPECT_LE(stats.nodes, tree.size());
          EXPECT_GE(stats.inserts, std::size_t(k));
          EXPECT_LE(stats.inserts, stats.nodes);
          EXPECT_LE(stats.pops, stats.pushes);
        }
      }
    }
  }
}

TEST(KdTreeTest, HeapReuseAcrossShrinkingAndGrowingK) {
  // NearestPhotons keeps its storage across queries; a smaller k after a larger one (and a
  // larger one again) must still give exactly the brute-force results.
  KdTree tree(KdSplitRule::kWidestExtent);
  tree.AddPhotons(Photons(Shape::kUniform, 5000, 11));
  tree.PrepareForQuery();
  NearestPhotons heap;
  const Vec3 x{0.4f, 0.5f, 0.6f};
  for (int k : {200, 3, 50, 1, 400, 7}) {
    tree.Query(x, k, std::numeric_limits<float>::infinity(), heap);
    const auto expected = BruteForceNearest(tree.photons(), x, k, std::numeric_limits<float>::infinity());
    ASSERT_EQ(heap.size(), expected.size());
    ASSERT_EQ(heap.entries().size(), expected.size());
    EXPECT_EQ(heap.MaxDistanceSquared(), expected.back().distance2);
    heap.Sort();
    for (std::size_t j = 0; j < expected.size(); ++j) ASSERT_EQ(heap[j].distance2, expected[j].distance2);
  }
}

}  // namespace
}  // namespace pf
