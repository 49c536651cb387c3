#pragma once
// A bucketed, unbalanced kd-tree for fast exact k-NN photon queries: the option beside the
// thesis's left-balanced tree (kdtree.h, Wald 1999 §2.3), after Wald et al., "Balancing
// Considered Harmful — Faster Photon Mapping using the Voxel Volume Heuristic" (2004), who
// measured unbalanced trees with leaf buckets 1.2–3.4× faster than balanced ones.
//
// What differs from the left-balanced tree, and why:
// * Photons live only in the leaves ("buckets" of at most leaf_size photons, contiguous in the
//   post-build photon order); inner nodes hold a split plane only (8 bytes each, depth-first
//   order: the left child follows its parent, the right child's index is stored).
// * The query path reads positions from a structure-of-arrays copy (x[], y[], z[] floats in
//   post-build order, 12 bytes per photon): one bucket's 8 x's are one 32-byte load, so the
//   distances of a whole bucket are computed at once (AVX2 8-wide, chosen at run time with
//   __builtin_cpu_supports; SSE 2×4-wide otherwise — the build targets x86-64-v2). The 18-byte
//   photon (photon.h, §2.2) stays the stored record: power and direction are read from it only
//   for the photons an estimator uses, and `photon(i)` / `photons()` work as for every map.
//   Memory: 18 + 12 bytes per photon + about 8 bytes per bucket.
// * Splits (BucketSplit): kMedian — the median on the widest extent of the node's bounding
//   box (balanced, depth ≈ log2(N / leaf_size)); kMidpoint — the middle of the widest extent
//   ("sliding midpoint": if one side would be empty, the split slides to the nearest photon).
//   Midpoint cells stay nearly cubic in sparse and dense regions alike, which is what the
//   voxel volume heuristic rewards for the fixed-size ball of a k-NN query; median cells
//   follow the photon density.
//
// Query: descend to the bucket containing x, test its photons, then visit the far children
// nearest-first from an explicit stack, culling a far child by the squared distance from x to
// its whole cell (per-axis offsets, as KdCulling::kCellDistance in kdtree.h).
//
// Exactness (results equal brute force's as distance multisets, like every PhotonMap): the
// SIMD distances only *select* candidates against a bound enlarged by 2^-16 relative; every
// candidate's distance is then recomputed by DistanceSquared (photon.h) from the same floats,
// and only that value is compared and inserted. So a compiler contracting a*b+c into FMA in
// either path cannot change a result. A cell's culling distance is a lower bound in float of
// every photon's DistanceSquared in it (per-axis |x − p| ≥ |x − plane|, rounding is monotonic,
// same summation order); it is also shrunk by 2^-16 relative for the same FMA reason.
//
// Determinism: no randomness, no threads; the same photons in the same order give the same
// tree, post-build order and results.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/photon/photon_map.h"

namespace pf {

class BucketKdTree final : public PhotonMap {
 public:
  explicit BucketKdTree(const BucketKdOptions& options = {});

  const BucketKdOptions& options() const { return options_; }
  std::size_t node_count() const { return nodes_.size(); }
  std::size_t leaf_count() const { return leaves_; }
  int depth() const { return depth_; }
  // Which leaf kernel queries use: "avx2" or "sse" (decided at construction).
  const char* simd() const;

  std::size_t MemoryBytes() const override;

  // Inner node: split position and (axis | right child << 2), axis ∈ {0, 1, 2}.
  // Leaf: first photon (bits of `split`) and (3 | count << 2).
  struct Node {
    float split;
    uint32_t bits;
  };

 protected:
  void Build() override;
  void DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const override;
  // QueryWithHint's first pass without a heap: the hint ball's photons into a flat buffer, the
  // k nearest selected once (BallCollector).
  bool DoQueryBall(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const override;

 private:
  BucketKdOptions options_;
  bool avx2_ = false;
  std::vector<Node> nodes_;
  std::vector<float> xs_, ys_, zs_;  // post-build order, + kPad readable floats at the end
  std::size_t leaves_ = 0;
  int depth_ = 0;
};

}  // namespace pf
