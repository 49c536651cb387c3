#pragma once
// The 3d-tree photon map of Wald 1999, §2.3: a left-balanced, complete kd-tree stored in the
// photon array itself, without pointers.
//
// Layout: tree node i ∈ [1, N] is photon(i − 1); its children are nodes 2i and 2i + 1
// (valid iff ≤ N). Since the tree is complete ("all levels filled except the last, which is
// filled from left to right", §2.3), nodes 1..N are exactly the array.
//
// kd-condition (§2.3, eq. 2.7): for every node, every photon of its left subtree has a
// coordinate ≤ the node's on the node's split axis, and every photon of its right subtree ≥.
//
// Split axis:
// * KdSplitRule::kLevelCycle — `level % 3`, level = depth of the node (root 0). The axis
//   follows from the node number, so the tree needs no memory beyond the 18-byte photons.
// * KdSplitRule::kWidestExtent — the axis of the largest extent of the subtree's bounding
//   box (§2.3, footnote 2; better for flat scenes such as SCENE10). The photon has no spare
//   byte (photon.h), so the axes live in a side array of 2 bits per node (N/4 bytes, i.e.
//   18.25 bytes per photon in total).
//
// Build (PrepareForQuery): the in-place BuildTree of §2.3 — see kdtree.cpp. Expected
// O(N log N), no memory beyond the photon array except O(log N) bookkeeping per recursion
// level and one fixed 18 KB buffer for subtrees of ≤ 1024 photons (and the axis array for
// kWidestExtent).
// With build_threads() ≠ 1 the two subtrees of every node heading ≥ 32k photons are balanced
// concurrently (TBB); the top splits are serial. Each subtree's result depends only on its own
// photons, so the array is the same for any thread count (tests/common/kdtree_test.cpp).
//
// Query: the thesis's backtracking search (§2.3.2): descend into the child on the query
// point's side first, and visit the other child later only if its culling distance is still
// below the heap's current bound. The culling distance is the thesis's splitting-plane
// distance (KdCulling::kPlaneDistance) or, by default, the distance to the far child's whole
// cell (KdCulling::kCellDistance; both are exact, the second culls more). Iterative with an
// explicit stack of depth ≤ 31; each descent runs to a leaf first and the photons of its path
// are tested bottom-up, so the nearby photons fill the heap before the far root-path ones
// (kdtree.cpp). The grandchildren are prefetched because below the cache-resident top of the
// tree every node is a cache miss.
//
// Build cost of kWidestExtent: one pass per level for the subtrees' bounding boxes (SSE
// min/max per photon); the trees are the same as with an exact scalar box.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "common/photon/photon_map.h"

namespace pf {

class KdTree final : public PhotonMap {
 public:
  explicit KdTree(KdSplitRule rule = KdSplitRule::kLevelCycle, KdCulling culling = KdCulling::kCellDistance)
      : rule_(rule), culling_(culling) {}

  KdSplitRule split_rule() const { return rule_; }
  KdCulling culling() const { return culling_; }
  // Split axis (0 = x, 1 = y, 2 = z) of tree node `node` ∈ [1, size()] (node i holds
  // photon(i − 1)). For leaves the value is meaningless. Requires a prepared map.
  int SplitAxis(std::size_t node) const;

  // Traversal counters of one query (benchmarks and tests; Query itself keeps no counters).
  struct SearchStats {
    uint64_t nodes = 0;    // photons (tree nodes) whose distance was computed
    uint64_t inserts = 0;  // heap insertions
    uint64_t pushes = 0;   // far children considered (nodes with a far child, popped)
    uint64_t pops = 0;     // far children not culled, i.e. descended into
  };
  // Exactly Query(x, k, max_radius, nearest, filter), counting into *stats (added to it).
  void QueryWithStats(const Vec3& x, int k, float max_radius, NearestPhotons& nearest, SearchStats* stats,
                      const PhotonFilter* filter = nullptr) const;

  // The 2-bit split axes of kWidestExtent (empty for kLevelCycle), indexed by node number:
  // with photons() the whole tree, what a serialized map carries (photon_maps_bytes.h).
  const std::vector<uint8_t>& stored_axes() const { return axes_; }
  // A prepared tree from an array that is already left-balanced in heap order (photons() and
  // stored_axes() of a built tree): no build, the same queries bit for bit. Throws
  // std::invalid_argument if the sizes do not fit (axes: photons / 4 + 1 bytes for
  // kWidestExtent, none for kLevelCycle) or a position is not finite; the kd-condition itself
  // is not checked (O(N log N)): the caller verifies the bytes' digest.
  static std::unique_ptr<KdTree> FromBalanced(KdSplitRule rule, KdCulling culling,
                                              std::vector<Photon> photons, std::vector<uint8_t> axes);

  std::size_t MemoryBytes() const override {
    return PhotonMap::MemoryBytes() + axes_.capacity() * sizeof(uint8_t);
  }

 protected:
  void Build() override;
  void DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const override;

 private:
  template <bool kStoredAxes, bool kCellDistance, bool kStats = false>
  void Search(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter,
              SearchStats* stats = nullptr) const;
  template <bool kStoredAxes, bool kCellDistance, bool kStats, bool kFilter>
  void SearchImpl(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter,
                  SearchStats* stats) const;
  void BuildSubtree(uint64_t root, int level);
  int StoredAxis(uint64_t node) const { return (axes_[node >> 2] >> ((node & 3) * 2)) & 3; }

  KdSplitRule rule_;
  KdCulling culling_;
  std::vector<uint8_t> axes_;  // kWidestExtent only: 2 bits per node, indexed by node number
};

}  // namespace pf
