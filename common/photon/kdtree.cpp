#include "common/photon/kdtree.h"

#include <immintrin.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <limits>
#include <stdexcept>
#include <utility>

namespace pf {
namespace {

// Wald 1999, §2.3: the photons of a subtree are not stored contiguously (figure 2.2: the
// subtree under node 4 is 4, 8, 9, 16..19, 32..39, ...), so the thesis walks a subtree with an
// `Index` iterator that enumerates it in level order: `node++`, and when `node >> level`
// leaves the subtree's prefix `mask`, descend: `node = mask << ++level`. Each level of a
// subtree is thus one contiguous run of nodes.
//
// We keep that idea but materialise the runs (one per level, at most 32) so that the walk
// can also go *backwards*, which a Hoare-style partition needs, and so that one sequence can
// chain three parts:
//
//     [left subtree in level order] [root] [right subtree in level order]
//
// If this sequence is partitioned such that position |left| holds the element of rank
// |left| on the split axis, every left element is ≤ it and every right element ≥ it: that
// is exactly the kd-condition for the root (§2.3, eq. 2.7), with the root's position being
// the one the left-balanced shape dictates. A quickselect over the sequence does it in
// expected linear time; the thesis's BuildTree is a QuickSort-partitioning variant of the
// same idea.
struct Run {
  uint64_t first;  // node numbers [first, last]
  uint64_t last;
  int64_t begin;  // sequence position of `first`
};

// A position in a SubtreeSequence: the node it denotes and its sequence position.
struct Cursor {
  const Run* run;
  uint64_t node;
  int64_t pos;

  // Moving past either end lands on a sentinel run and is fine as long as the cursor is not
  // dereferenced (the partition below never does).
  void Next() {
    ++pos;
    if (++node > run->last) {
      ++run;
      node = run->first;
    }
  }
  void Prev() {
    --pos;
    if (node-- == run->first) {
      --run;
      node = run->last;
    }
  }
};

class SubtreeSequence {
 public:
  // The subtree under `root` (which must have at least one child) of a tree with n nodes.
  SubtreeSequence(uint64_t root, uint64_t n) {
    runs_[0] = Run{0, 0, -1};  // sentinel before the first run
    count_ = 1;
    AddLevels(2 * root, n);
    left_size_ = size_;
    AddRun(root, root);
    AddLevels(2 * root + 1, n);
    runs_[count_] = Run{0, 0, size_};  // sentinel after the last run
  }

  int64_t size() const { return size_; }
  int64_t left_size() const { return left_size_; }
  const Run* begin() const { return &runs_[1]; }
  const Run* end() const { return &runs_[count_]; }

  // Random access, used only to pick pivot candidates: O(number of runs).
  Cursor At(int64_t pos) const {
    const Run* r = begin();
    while (pos >= r->begin + int64_t(r->last - r->first) + 1) ++r;
    return {r, r->first + uint64_t(pos - r->begin), pos};
  }

 private:
  // Level order of the subtree under `sub`, exactly the thesis's Index walk: level d is the
  // run [sub << d, (sub << d) + 2^d − 1], cut off at n.
  void AddLevels(uint64_t sub, uint64_t n) {
    for (uint64_t first = sub, width = 1; first <= n; first <<= 1, width <<= 1)
      AddRun(first, std::min(first + width - 1, n));
  }
  void AddRun(uint64_t first, uint64_t last) {
    runs_[count_++] = Run{first, last, size_};
    size_ += int64_t(last - first) + 1;
  }

  // 2 sentinels + 1 root + at most 32 levels on each side (n < 2^31). Left uninitialised:
  // this is built for every inner node, and only the used entries are ever read.
  std::array<Run, 2 + 1 + 2 * 32> runs_;
  int count_ = 0;
  int64_t size_ = 0;
  int64_t left_size_ = 0;
};

// Bounding box of photon positions, one SSE min and max per photon (§2.3, footnote 2: the
// widest-extent rule needs the box of every subtree, i.e. a pass over each level; in scalar
// code that pass was ~30% of the build). Loads 16 bytes at the photon's start: the 3 position
// floats plus 4 bytes of direction/power whose lane is ignored (all within the 18 bytes).
class BoxAccumulator {
 public:
  void Add(const Photon& p) {
    const __m128 v = _mm_loadu_ps(p.position);
    lo_ = _mm_min_ps(lo_, v);
    hi_ = _mm_max_ps(hi_, v);
  }
  // The axis of the largest extent (ties: x before y before z, as before).
  int WidestAxis() const {
    alignas(16) float lo[4], hi[4];
    _mm_store_ps(lo, lo_);
    _mm_store_ps(hi, hi_);
    const float dx = hi[0] - lo[0], dy = hi[1] - lo[1], dz = hi[2] - lo[2];
    return dx >= dy ? (dx >= dz ? 0 : 2) : (dy >= dz ? 1 : 2);
  }

 private:
  __m128 lo_ = _mm_set1_ps(std::numeric_limits<float>::max());
  __m128 hi_ = _mm_set1_ps(-std::numeric_limits<float>::max());
};

class Builder {
 public:
  // Subtrees of at least `parallel_min` photons have their two children built concurrently.
  Builder(std::vector<Photon>& photons, KdSplitRule rule, std::vector<uint8_t>& axes, uint64_t parallel_min)
      : photons_(photons), n_(photons.size()), rule_(rule), axes_(axes), parallel_min_(parallel_min) {}
  // Another builder on the same tree, with its own small-subtree buffer (for a concurrent task).
  Builder(const Builder& other) : Builder(other.photons_, other.rule_, other.axes_, other.parallel_min_) {}
  Builder& operator=(const Builder&) = delete;

  // Wald 1999, §2.3, BuildTree(p, N, root, level): establish the kd-condition at `root` by
  // partitioning its subtree, then recurse into both children. Recursion depth ≤ 32.
  //
  // Threads: once `root` is split, its two subtrees own disjoint node sets (their level runs
  // never overlap) and each one's final content depends only on the photons in its own nodes,
  // so they can be built concurrently and the array is the same for any thread count or
  // schedule. The top splits stay serial (one Select over the whole subtree each).
  void Build(uint64_t root, int level) {
    if (2 * root > n_) return;  // a leaf: nothing below it to partition
    const uint64_t size = SubtreeSize(root);
    if (size <= kSmallSubtree) {
      BuildSmall(root, level, size);
      return;
    }
    const SubtreeSequence seq(root, n_);
    int axis = level % 3;
    if (rule_ == KdSplitRule::kWidestExtent) {
      axis = WidestAxis(seq);
      StoreAxis(root, axis);
    }
    Select(seq, seq.left_size(), axis);
    if (size >= parallel_min_) {
      tbb::parallel_invoke([&] { Builder(*this).Build(2 * root, level + 1); },
                           [&] { Build(2 * root + 1, level + 1); });
      return;
    }
    Build(2 * root, level + 1);
    Build(2 * root + 1, level + 1);
  }

 private:
  Photon& At(const Cursor& c) { return photons_[c.node - 1]; }
  // Four nodes share a byte of the axis array, and nodes of concurrently built subtrees may
  // be among them (siblings and first cousins): an atomic OR keeps every writer's bits.
  void StoreAxis(uint64_t node, int axis) {
    std::atomic_ref<uint8_t>(axes_[node >> 2])
        .fetch_or(uint8_t(axis << ((node & 3) * 2)), std::memory_order_relaxed);
  }
  float Key(const Cursor& c, int axis) { return photons_[c.node - 1].position[axis]; }
  void Swap(const Cursor& a, const Cursor& b) { std::swap(At(a), At(b)); }

  // §2.3, footnote 2: the dimension of the subtree's largest bounding-box extent.
  int WidestAxis(const SubtreeSequence& seq) {
    BoxAccumulator box;
    for (const Run* r = seq.begin(); r != seq.end(); ++r)
      for (uint64_t node = r->first; node <= r->last; ++node) box.Add(photons_[node - 1]);
    return box.WidestAxis();
  }

  // Quickselect (Hoare 1961) over the sequence: afterwards position `target` holds the
  // element of that rank on `axis`, everything before it is ≤ and everything after it ≥.
  // Median-of-three pivots and Hoare's partition (which splits runs of equal keys evenly, so
  // planar scenes and duplicate positions stay O(m) per subtree) give expected O(m).
  void Select(const SubtreeSequence& seq, int64_t target, int axis) {
    int64_t lo = 0, hi = seq.size() - 1;
    while (hi - lo > kInsertionSortSize) {
      Cursor a = seq.At(lo), b = seq.At(lo + (hi - lo) / 2), c = seq.At(hi);
      if (Key(b, axis) < Key(a, axis)) Swap(a, b);
      if (Key(c, axis) < Key(a, axis)) Swap(a, c);
      if (Key(c, axis) < Key(b, axis)) Swap(b, c);
      Swap(a, b);  // the median of the three is now the pivot at `lo`; `hi` holds one ≥ it
      const float pivot = Key(a, axis);
      // Hoare's partition with both cursors walking the (non-contiguous) sequence.
      Cursor i = a, j = c;
      for (;;) {
        while (Key(i, axis) < pivot) i.Next();
        while (Key(j, axis) > pivot) j.Prev();
        if (i.pos >= j.pos) break;
        Swap(i, j);
        i.Next();
        j.Prev();
      }
      // [lo, j] ≤ pivot ≤ [j + 1, hi], and lo ≤ j < hi: both sides shrink.
      if (target <= j.pos) {
        hi = j.pos;
      } else {
        lo = j.pos + 1;
      }
    }
    InsertionSort(seq, lo, hi, axis);
  }

  void InsertionSort(const SubtreeSequence& seq, int64_t lo, int64_t hi, int axis) {
    if (hi <= lo) return;
    Cursor c = seq.At(lo);
    for (c.Next(); c.pos <= hi; c.Next()) {
      const Photon moving = At(c);
      const float key = moving.position[axis];
      Cursor hole = c;
      while (hole.pos > lo) {
        Cursor prev = hole;
        prev.Prev();
        if (!(Key(prev, axis) > key)) break;
        At(hole) = At(prev);
        hole = prev;
      }
      At(hole) = moving;
    }
  }

  // Number of nodes in the subtree under `root`: the thesis's Index walk, level by level.
  uint64_t SubtreeSize(uint64_t root) const {
    uint64_t size = 0;
    for (uint64_t first = root, width = 1; first <= n_; first <<= 1, width <<= 1)
      size += std::min(width, n_ - first + 1);
    return size;
  }

  // The bottom of the tree: most nodes head tiny subtrees, for which the sequence
  // bookkeeping above costs more than the partitioning itself. Such a subtree (≤ 1024
  // photons) is copied into a fixed 18 KB buffer, built there by the same median
  // partitioning on contiguous ranges, and written back to its node positions. The memory
  // stays O(1), and the result satisfies the same kd-condition.
  void BuildSmall(uint64_t root, int level, uint64_t size) {
    std::size_t m = 0;
    for (uint64_t first = root, width = 1; first <= n_; first <<= 1, width <<= 1) {
      const uint64_t last = std::min(first + width - 1, n_);
      for (uint64_t node = first; node <= last; ++node) small_[m++] = photons_[node - 1];
    }
    Place(root, level, small_.data(), std::size_t(size));
  }
  void Place(uint64_t node, int level, Photon* photons, std::size_t m) {
    if (m == 0) return;
    if (m == 1) {
      photons_[node - 1] = photons[0];
      return;
    }
    int axis = level % 3;
    if (rule_ == KdSplitRule::kWidestExtent) {
      BoxAccumulator box;
      for (std::size_t i = 0; i < m; ++i) box.Add(photons[i]);
      axis = box.WidestAxis();
      StoreAxis(node, axis);
    }
    const std::size_t left = std::size_t(SubtreeSize(2 * node));
    std::nth_element(photons, photons + left, photons + m, [axis](const Photon& a, const Photon& b) {
      return a.position[axis] < b.position[axis];
    });
    photons_[node - 1] = photons[left];
    Place(2 * node, level + 1, photons, left);
    Place(2 * node + 1, level + 1, photons + left + 1, m - left - 1);
  }

  static constexpr int64_t kInsertionSortSize = 12;
  static constexpr uint64_t kSmallSubtree = 1024;
  std::array<Photon, kSmallSubtree> small_;

  std::vector<Photon>& photons_;
  uint64_t n_;
  KdSplitRule rule_;
  std::vector<uint8_t>& axes_;
  uint64_t parallel_min_;
};

// Below this many photons a subtree is built by the task that split its parent: a task costs
// microseconds, a subtree of 32k photons milliseconds.
constexpr uint64_t kParallelSubtree = 32768;

}  // namespace

void KdTree::Build() {
  axes_.clear();
  if (rule_ == KdSplitRule::kWidestExtent) {
    axes_.assign(photons_.size() / 4 + 1, 0);
    axes_.shrink_to_fit();
  } else {
    axes_.shrink_to_fit();
  }
  if (build_threads_ == 1 || photons_.size() < 2 * kParallelSubtree) {
    Builder(photons_, rule_, axes_, std::numeric_limits<uint64_t>::max()).Build(1, 0);
    return;
  }
  tbb::task_arena arena(build_threads_ > 0 ? build_threads_ : tbb::task_arena::automatic);
  arena.execute([&] { Builder(photons_, rule_, axes_, kParallelSubtree).Build(1, 0); });
}

std::unique_ptr<KdTree> KdTree::FromBalanced(KdSplitRule rule, KdCulling culling, std::vector<Photon> photons,
                                             std::vector<uint8_t> axes) {
  if (photons.size() > kMaxPhotons) throw std::invalid_argument("KdTree::FromBalanced: too many photons");
  const size_t want_axes =
      rule == KdSplitRule::kWidestExtent && !photons.empty() ? photons.size() / 4 + 1 : 0;
  if (axes.size() != want_axes)
    throw std::invalid_argument("KdTree::FromBalanced: " + std::to_string(axes.size()) + " axis bytes for " +
                                std::to_string(photons.size()) + " photons (expected " +
                                std::to_string(want_axes) + ")");
  for (const Photon& p : photons)
    if (!IsFinite(p.Position()))
      throw std::invalid_argument("KdTree::FromBalanced: non-finite photon position");
  auto tree = std::make_unique<KdTree>(rule, culling);
  tree->photons_ = std::move(photons);
  tree->axes_ = std::move(axes);
  tree->prepared_ = true;
  return tree;
}

int KdTree::SplitAxis(std::size_t node) const {
  if (rule_ == KdSplitRule::kWidestExtent) return StoredAxis(node);
  return (std::bit_width(node) - 1) % 3;
}

void KdTree::DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const {
  const bool stored = rule_ == KdSplitRule::kWidestExtent;
  const bool cell = culling_ == KdCulling::kCellDistance;
  if (stored) {
    cell ? Search<true, true>(x, nearest, filter) : Search<true, false>(x, nearest, filter);
  } else {
    cell ? Search<false, true>(x, nearest, filter) : Search<false, false>(x, nearest, filter);
  }
}

// Wald 1999, §2.3.2: backtracking k-NN search, with the nodes of each descent processed
// bottom-up. The thesis processes a node's photon on the way down; then the first photons in
// the heap are those of the root path, which lie far from x (the root splits the whole
// scene), and while they fill the heap its bound stays loose and the nearby subtrees are
// searched with it. Here a descent first goes down to a leaf along x's side of every
// splitting plane, only reading each node's split coordinate (and computing its photon's
// distance, the cache line being loaded anyway) and pushing the node. Popping a node then
// processes its photon and, if its culling distance is still below the bound, descends into
// its far child the same way. So the photons near x enter the heap first, the bound is tight
// early, and most root-path photons are rejected by one comparison instead of entering the
// heap and being evicted again. The stack holds one entry per node of the current path
// (≤ 31 for n < 2^31). The visited set is the thesis's (a node is reached iff its cell is not
// culled), only the order differs, and that order culls more.
//
// Exactness: every culling distance is a lower bound, *in float*, of DistanceSquared for all
// photons of the culled subtree: per axis, a photon lies beyond each ancestor's plane, so
// |x − photon| ≥ |x − plane| after rounding too (rounding is monotonic), and the cell
// distance sums the per-axis terms in DistanceSquared's order. Hence the results equal brute
// force's exactly (as distance multisets).
void KdTree::QueryWithStats(const Vec3& x, int k, float max_radius, NearestPhotons& nearest,
                            SearchStats* stats, const PhotonFilter* filter) const {
  nearest.Reset(k, max_radius);
  if (!prepared_) throw std::logic_error("PhotonMap::Query before PrepareForQuery");
  if (nearest.k() == 0 || photons_.empty() || !IsFinite(x) || !(nearest.BoundSquared() > 0.0f)) return;
  const bool stored = rule_ == KdSplitRule::kWidestExtent;
  const bool cell = culling_ == KdCulling::kCellDistance;
  if (stored) {
    cell ? Search<true, true, true>(x, nearest, filter, stats)
         : Search<true, false, true>(x, nearest, filter, stats);
  } else {
    cell ? Search<false, true, true>(x, nearest, filter, stats)
         : Search<false, false, true>(x, nearest, filter, stats);
  }
}

template <bool kStoredAxes, bool kCellDistance, bool kStats>
void KdTree::Search(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter,
                    SearchStats* stats) const {
  if (filter == nullptr) {
    SearchImpl<kStoredAxes, kCellDistance, kStats, false>(x, nearest, nullptr, stats);
  } else {
    SearchImpl<kStoredAxes, kCellDistance, kStats, true>(x, nearest, filter, stats);
  }
}

template <bool kStoredAxes, bool kCellDistance, bool kStats, bool kFilter>
void KdTree::SearchImpl(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter,
                        SearchStats* stats) const {
  const Photon* photons = photons_.data();
  const uint8_t* axes = axes_.data();
  const uint32_t n = uint32_t(photons_.size());
  const float q[3] = {x.x, x.y, x.z};

  struct Pending {
    uint32_t node;      // a node of the current path whose photon is not processed yet
    uint32_t far;       // its far child (> n: none)
    uint32_t far_axis;  // kLevelCycle: the far child's split axis
    float d2;           // the node's photon's squared distance to x
    float off[3];       // per-axis offsets from x to the far child's cell (kPlaneDistance:
                        // off[0] is the offset to the node's plane)
  };
  std::array<Pending, 32> stack;
  int top = 0;

  float bound2 = nearest.BoundSquared();
  uint32_t node = 1, axis = 0;
  float off[3] = {0.0f, 0.0f, 0.0f};  // offsets of the current node's cell (x is inside: 0)
  for (;;) {
    // Descend along x's side of each plane; the near child's cell is as far from x as its
    // parent's, so only the far children get new offsets.
    do {
      // Nodes 4i..4i+3 are 72 contiguous bytes (two cache lines): the near grandchildren are
      // needed two steps from now, the far ones maybe later.
      if (4 * node + 3 <= n) {
        __builtin_prefetch(&photons[4 * node - 1]);
        __builtin_prefetch(&photons[4 * node + 2]);
      }
      const Photon& p = photons[node - 1];
      if constexpr (kStats) ++stats->nodes;
      if constexpr (kStoredAxes) axis = (axes[node >> 2] >> ((node & 3) * 2)) & 3u;
      const float d = q[axis] - p.position[axis];
      // Left subtree ≤ split ≤ right subtree: x on the right side (d ≥ 0) → right is near.
      const uint32_t near_child = 2 * node + (d >= 0.0f ? 1u : 0u);
      Pending& e = stack[top++];
      e.node = node;
      e.far = near_child ^ 1u;
      e.d2 = DistanceSquared(p, x);
      if constexpr (kCellDistance) {
        e.off[0] = off[0];
        e.off[1] = off[1];
        e.off[2] = off[2];
        e.off[axis] = d;
      } else {
        e.off[0] = d;
      }
      if constexpr (!kStoredAxes) axis = axis == 2 ? 0 : axis + 1;
      e.far_axis = axis;
      node = near_child;
    } while (node <= n);
    // Unwind: process the path's photons bottom-up until a far child needs a visit.
    for (;;) {
      if (top == 0) return;
      const Pending& e = stack[--top];
      if (e.d2 < bound2 && (!kFilter || filter->Accept(photons[e.node - 1], e.node - 1))) {
        nearest.Insert(e.node - 1, e.d2);
        bound2 = nearest.BoundSquared();
        if constexpr (kStats) ++stats->inserts;
      }
      if (e.far <= n) {
        if constexpr (kStats) ++stats->pushes;
        const float cull2 = kCellDistance ? (e.off[0] * e.off[0] + e.off[1] * e.off[1]) + e.off[2] * e.off[2]
                                          : e.off[0] * e.off[0];
        if (cull2 < bound2) {
          if constexpr (kStats) ++stats->pops;
          node = e.far;
          axis = e.far_axis;
          if constexpr (kCellDistance) {
            off[0] = e.off[0];
            off[1] = e.off[1];
            off[2] = e.off[2];
          }
          break;
        }
      }
    }
  }
}

}  // namespace pf
