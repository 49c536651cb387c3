#pragma once
// The photon map interface of Wald 1999, §2.2: photons are stored with AddPhoton during the
// random walk, the acceleration structure is built once by PrepareForQuery, and Query finds
// the k nearest photons around a point into a max-heap (the thesis's "PhotonList").
//
// Three implementations (PhotonMapKind): the left-balanced kd-tree of §2.3 (kdtree.h), the
// regular grid of §2.4 (grid.h) and a bucketed, unbalanced kd-tree (bucket_kdtree.h, after Wald
// et al. 2004), built by name through photon_map_factory.h. Each keeps the photons in one
// dynamic array and reorders it in place; after PrepareForQuery, `photon(i)` is the i-th photon
// in that post-build order and the indices returned by Query refer to it.
//
// Query semantics (all three implementations, and brute_force.h, agree on them exactly):
// * the search region is the *open* ball: a photon is a candidate iff its squared distance
//   (DistanceSquared in photon.h) is < max_radius²; max_radius = +inf means unbounded, and
//   max_radius ≤ 0 or NaN finds nothing;
// * the result is the min(k, #candidates) candidates of smallest distance; ties at the k-th
//   distance are broken arbitrarily, so results are unique only as distance multisets;
// * an optional PhotonFilter is applied *inside* the query (the "in-query" variant of
//   §4.1): only accepted photons enter the heap, so the heap holds the k nearest *accepted*
//   photons (always k if that many exist). The filter runs after the distance test, i.e. only
//   for photons that would otherwise enter the heap;
// * a query at a non-finite point finds nothing.
//
// Determinism (docs/design.md, G1): builds use no randomness, and threads only on disjoint parts
// whose result does not depend on timing, so the same photons added in the same order give the
// same post-build order and the same query results (including tie-breaking) on every run and
// for any build_threads().
//
// Threads: after PrepareForQuery the map is immutable and Query is const and touches no
// shared mutable state, so any number of threads may query one map concurrently as long as
// each passes its own NearestPhotons (which carries all per-query scratch, e.g. the grid's
// visited-voxel tags). AddPhoton/PrepareForQuery must not run concurrently with anything.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include "common/core/math.h"
#include "common/photon/photon.h"

namespace pf {

// An in-query feasibility test (Wald 1999, §4.1), e.g. "the photon arrives from the front
// side of the surface at x". Must be thread-safe if the map is queried from several threads.
class PhotonFilter {
 public:
  virtual ~PhotonFilter() = default;
  // `index` is the photon's post-build index (PhotonMap::photon(index) == photon).
  virtual bool Accept(const Photon& photon, std::size_t index) const = 0;
};

// Adapts any callable `bool(const Photon&, std::size_t)` to a PhotonFilter.
template <typename Fn>
class FunctionFilter final : public PhotonFilter {
 public:
  explicit FunctionFilter(Fn fn) : fn_(std::move(fn)) {}
  bool Accept(const Photon& photon, std::size_t index) const override { return fn_(photon, index); }

 private:
  Fn fn_;
};

// The result of a query and the caller-owned state of one querying thread: a bounded
// max-heap of (photon index, squared distance) — the thesis's PhotonList (§2.3.2) — plus the
// scratch memory a grid query needs. Reuse one object per thread across queries: after the
// first few queries no query allocates.
class NearestPhotons {
 public:
  struct Entry {
    uint32_t index;   // post-build photon index
    float distance2;  // squared distance to the query point
  };

  NearestPhotons() = default;

  // Empties the heap and sets the capacity k (negative → 0) and the search radius.
  void Reset(int k, float max_radius) {
    k_ = k > 0 ? std::size_t(k) : 0;
    size_ = 0;
    if (heap_.size() < k_) heap_.resize(k_);  // storage only grows: no allocation after warm-up
    radius2_ = max_radius > 0.0f ? max_radius * max_radius : 0.0f;  // NaN → 0: finds nothing
    bound2_ = k_ > 0 ? radius2_ : 0.0f;
  }

  std::size_t k() const { return k_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  bool full() const { return size_ == k_; }

  // The exclusive acceptance bound of the running query: a photon can still enter the heap
  // iff its squared distance is < BoundSquared(). It is max_radius² until the heap is full
  // and the current k-th distance² (the heap's maximum) afterwards. Queries cull against it.
  float BoundSquared() const { return bound2_; }
  // The largest squared distance among the photons found (0 if none): r² of the radiance
  // estimate Σ ΔΦ / (π r²) (§2.5).
  float MaxDistanceSquared() const { return size_ == 0 ? 0.0f : heap_[0].distance2; }

  // The entries, the first one the farthest: after Query in max-heap order, after a
  // QueryWithHint the rest in no particular order (BallCollector). Use Sort() for distance
  // order.
  std::span<const Entry> entries() const { return {heap_.data(), size_}; }
  const Entry& operator[](std::size_t i) const { return heap_[i]; }

  // Adds a candidate; requires distance2 < BoundSquared(). Replaces the farthest entry if
  // the heap is full. O(log k). (Hot in every query: raw pointers, no bounds bookkeeping.)
  void Insert(uint32_t index, float distance2) {
    Entry* const h = heap_.data();
    if (size_ < k_) {
      SiftUp(h, size_++, {index, distance2});
      if (size_ == k_) bound2_ = h[0].distance2;
    } else {
      SiftDown(h, size_, {index, distance2});
      bound2_ = h[0].distance2;
    }
  }

  // Orders the entries by increasing distance (ties by index). Destroys the heap order: call
  // it only after the query, and Reset (i.e. run a new query) before inserting again.
  void Sort() {
    std::sort(heap_.begin(), heap_.begin() + std::ptrdiff_t(size_), [](const Entry& a, const Entry& b) {
      return a.distance2 < b.distance2 || (a.distance2 == b.distance2 && a.index < b.index);
    });
  }

 private:
  friend class GridPhotonMap;
  friend class BallCollector;

  // Places e, the new last entry at position i, by moving its larger ancestors down.
  static void SiftUp(Entry* h, std::size_t i, Entry e) {
    while (i > 0) {
      const std::size_t parent = (i - 1) / 2;
      if (!(h[parent].distance2 < e.distance2)) break;
      h[i] = h[parent];
      i = parent;
    }
    h[i] = e;
  }
  // Replaces the root (the farthest entry) of the full heap h[0, n) by e.
  static void SiftDown(Entry* h, std::size_t n, Entry e) {
    std::size_t i = 0;
    const std::size_t last_parent = n / 2;  // nodes < n/2 have at least one child
    while (i < last_parent) {
      std::size_t child = 2 * i + 1;
      float dc = h[child].distance2;
      if (child + 1 < n && dc < h[child + 1].distance2) dc = h[++child].distance2;
      if (!(e.distance2 < dc)) break;
      h[i] = h[child];
      i = child;
    }
    h[i] = e;
  }

  std::vector<Entry> heap_;  // entries [0, size_) form the heap; size() ≥ k_ after Reset
  std::size_t size_ = 0;
  std::size_t k_ = 0;
  float radius2_ = 0.0f;
  float bound2_ = 0.0f;

  // Scratch of GridPhotonMap queries (§2.4): a visited bit per voxel, set while a query runs
  // and cleared again at its end through the list of voxels it touched (so the bitmap is all
  // zero between queries and needs no per-query clearing or generation counter).
  struct GridScratch {
    std::vector<uint64_t> visited;
    std::vector<std::array<int32_t, 4>> fill;  // voxel (i, j, k, linear index), visiting order
  } grid_;
};

// The first pass of QueryWithHint without a heap (used by BucketKdTree::DoQueryBall).
//
// Inside a ball that holds a bit more than k photons (a good hint: the k-th distance of a
// neighbouring query × 1.2 holds ~1.44 k photons on a surface), the heap of Query (the
// thesis's PhotonList, Wald 1999 §2.3.2) is mostly overhead: every photon is sifted in, and a
// third of them are evicted again, with an unpredictable branch at every level. Instead every
// candidate of the ball is appended to a flat buffer, and the k nearest are selected once at
// the end, in O(count): the candidates are counted into bins by distance² while they are
// appended (bins linear in d², i.e. in the area of a disk, so photons on a surface fill them
// about evenly), the bin holding the k-th candidate is found from the counts, the bins below
// it are compacted to the front in one branch-free pass and only that one bin (a few
// entries) is ordered with nth_element. Bins are monotonic in d², so the result is k nearest
// photons, the same set on every run. Ties at the k-th distance keep the lower index unless the
// buffer filled (below): after that a later candidate at the lowered bound is refused, so on
// duplicate positions a hinted and an unhinted query may pick different (equally near) photons.
//
// The buffer holds Capacity(k) entries: when it is full, the k nearest so far are kept and
// their k-th distance² becomes the bound (exact: a photon at ≥ that bound cannot be among the
// k nearest). A good hint never fills it; the cap bounds memory and time for a far too large
// hint (e.g. one holding all N photons).
//
// The result is NearestPhotons' with the farthest entry first (the radiance estimate excludes
// it, §2.5) and the others in no particular order; it is not a heap.
class BallCollector {
 public:
  static constexpr int kBins = 64;
  static std::size_t Capacity(std::size_t k) { return std::max<std::size_t>(4 * k, k + 64); }

  // `nearest` is Reset to k ≥ 1 and the ball's radius (its BoundSquared() > 0).
  explicit BallCollector(NearestPhotons& nearest)
      : nearest_(nearest),
        k_(nearest.k()),
        capacity_(Capacity(nearest.k())),
        bound2_(nearest.BoundSquared()) {
    // The buffer and, behind it, the selection's scratch (grows only, like the heap).
    if (nearest.heap_.size() < 2 * capacity_) nearest.heap_.resize(2 * capacity_);
    buffer_ = nearest.heap_.data();
    // A denormal bound makes the scale +inf (and 0·inf NaN), +inf makes it 0: one bin then,
    // i.e. a plain nth_element over all candidates; still exact.
    scale_ = float(kBins) / bound2_;
    if (!(scale_ <= std::numeric_limits<float>::max())) scale_ = 0.0f;
  }

  // The exclusive bound: a candidate must have d2 < Bound().
  float Bound() const { return bound2_; }
  std::size_t size() const { return size_; }

  // Appends a candidate (d2 < Bound()); returns the bound from then on.
  float Add(uint32_t index, float d2) {
    buffer_[size_] = {index, d2};
    ++histogram_[Bin(d2)];
    if (++size_ == capacity_) Compact();
    return bound2_;
  }

  // Ends the pass: if the ball held at least k candidates, the k nearest become `nearest`'s
  // result and it returns true; otherwise `nearest` is left empty and it returns false.
  bool Finish() {
    if (size_ < k_) {
      nearest_.size_ = 0;
      return false;
    }
    if (size_ > k_) {
      Select();
    } else {
      // Exactly k: only the farthest must come first.
      std::size_t far = 0;
      for (std::size_t i = 1; i < k_; ++i)
        if (Closer(buffer_[far], buffer_[i])) far = i;
      std::swap(buffer_[0], buffer_[far]);
    }
    nearest_.size_ = k_;
    nearest_.bound2_ = buffer_[0].distance2;
    return true;
  }

 private:
  using Entry = NearestPhotons::Entry;
  static bool Closer(const Entry& a, const Entry& b) {
    return a.distance2 < b.distance2 || (a.distance2 == b.distance2 && a.index < b.index);
  }
  // Monotonic in d2 (a product with a positive constant and truncation both are), < kBins.
  int Bin(float d2) const { return std::min(int(d2 * scale_), kBins - 1); }

  // The k nearest of buffer_[0, size_) (size_ > k) to buffer_[0, k), the farthest of them
  // first.
  void Select() {
    int kth_bin = 0;
    std::size_t below = 0;  // candidates in the bins before kth_bin
    while (below + histogram_[kth_bin] < k_) below += histogram_[kth_bin++];
    Entry* const side = buffer_ + capacity_;
    std::size_t front = 0, in_bin = 0;
    for (std::size_t i = 0; i < size_; ++i) {
      const Entry e = buffer_[i];
      const int bin = Bin(e.distance2);
      buffer_[front] = e;  // front ≤ i: compaction in place
      front += bin < kth_bin ? 1 : 0;
      side[in_bin] = e;
      in_bin += bin == kth_bin ? 1 : 0;
    }
    const std::size_t need = k_ - below;  // 1 ≤ need ≤ in_bin
    std::nth_element(side, side + (need - 1), side + in_bin,
                     [](const Entry& a, const Entry& b) { return Closer(a, b); });
    std::copy(side, side + need, buffer_ + below);
    // side[need − 1] is the k-th: every entry of a lower bin is closer (bins are monotonic).
    std::swap(buffer_[0], buffer_[k_ - 1]);
  }

  // The buffer is full: keep the k nearest, bound = their k-th distance², recount the bins.
  void Compact() {
    Select();
    bound2_ = buffer_[0].distance2;
    size_ = k_;
    std::fill(std::begin(histogram_), std::end(histogram_), 0u);
    for (std::size_t i = 0; i < k_; ++i) ++histogram_[Bin(buffer_[i].distance2)];
  }

  NearestPhotons& nearest_;
  std::size_t k_;
  std::size_t capacity_;
  float bound2_;
  float scale_ = 0.0f;
  Entry* buffer_ = nullptr;
  std::size_t size_ = 0;
  uint32_t histogram_[kBins] = {};
};

// kKdTree: the thesis's left-balanced kd-tree (kdtree.h); kGrid: the regular grid (grid.h);
// kBucketKdTree: a bucketed, unbalanced kd-tree with SIMD bucket tests (bucket_kdtree.h).
enum class PhotonMapKind { kKdTree, kGrid, kBucketKdTree };

// kd-tree split dimension (Wald 1999, §2.3 and its footnote 2).
enum class KdSplitRule {
  kLevelCycle,    // level % 3: the thesis's rule; needs no storage
  kWidestExtent,  // the axis of the subtree's largest bounding-box extent; 2 bits per node
};

// kd-tree culling test for the far child of a node (Wald 1999, §2.3.2).
enum class KdCulling {
  // The thesis's test: squared distance from x to the node's splitting plane. Cheap, but it
  // ignores every other plane bounding the far subtree and so underestimates its distance.
  kPlaneDistance,
  // Squared distance from x to the far subtree's whole cell (the box cut out by all its
  // ancestors' planes), tracked per axis on the way down (Arya & Mount 1993). The thesis
  // found "more involved tests" not worth their overhead in 1999; today a cache miss costs
  // more than a few multiplies, and this test visits about half as many nodes.
  kCellDistance,
};

struct GridOptions {
  // The k most queries will use. The voxel size is chosen so that an occupied voxel holds
  // about `photons_per_voxel` photons; 0 picks it from expected_k (see grid.h).
  int expected_k = 50;
  float photons_per_voxel = 0.0f;
  // Upper bound on the number of voxels as a multiple of the photon count (memory: 4 bytes
  // per voxel in the map, 1 bit per voxel in each thread's NearestPhotons).
  double max_voxels_per_photon = 1.0;
};

// Split rule of the bucketed kd-tree (bucket_kdtree.h).
enum class BucketSplit {
  kMedian,    // median on the widest extent: balanced
  kMidpoint,  // middle of the widest extent, sliding to the nearest photon: near-cubic cells
};

struct BucketKdOptions {
  // Photons per bucket at most, in [1, 64]. 32: four 8-wide SIMD steps per bucket. Larger
  // buckets mean fewer inner nodes to descend and cull. photon_map_bench on 1M real photons
  // (docs/results/kernel.md §1, runs new1-3 against newleaf8, loaded machine): the hinted pass
  // (QueryWithHint) is faster at k ≥ 50 (k = 50: 2.66 → 1.81–2.47 µs on Cornell), about even
  // at k = 10; a plain Query is 2–10 % slower at k = 10 and at Cornell's k = 500. The renderer
  // queries hinted, at k = 50 … 100.
  int leaf_size = 32;
  BucketSplit split = BucketSplit::kMedian;
  // Use the AVX2 bucket kernel where the CPU has it (false: always the SSE one, e.g. to test
  // it on an AVX2 machine).
  bool allow_avx2 = true;
};

struct PhotonMapOptions {
  KdSplitRule kd_split_rule = KdSplitRule::kLevelCycle;
  KdCulling kd_culling = KdCulling::kCellDistance;
  GridOptions grid;
  BucketKdOptions bucket;
};

class PhotonMap {
 public:
  virtual ~PhotonMap() = default;
  PhotonMap() = default;
  // Movable, not copyable (a map may hold gigabytes; copy the photons() explicitly).
  PhotonMap(const PhotonMap&) = delete;
  PhotonMap& operator=(const PhotonMap&) = delete;
  PhotonMap(PhotonMap&&) = default;
  PhotonMap& operator=(PhotonMap&&) = default;

  // Storing (§2.2). Adding after PrepareForQuery is allowed but un-prepares the map.
  // Throws std::invalid_argument for a non-finite position (it could never be found, and it
  // would break the ordering the structures rely on).
  void AddPhoton(const Photon& photon) {
    CheckPosition(photon);
    photons_.push_back(photon);
    prepared_ = false;
  }
  void AddPhoton(const Vec3& position, const Vec3& direction, const Rgb& power) {
    AddPhoton(Photon::Make(position, direction, power));
  }
  void AddPhotons(std::span<const Photon> photons) {
    for (const Photon& p : photons) CheckPosition(p);
    photons_.insert(photons_.end(), photons.begin(), photons.end());
    prepared_ = false;
  }
  void Reserve(std::size_t n) { photons_.reserve(n); }
  // Threads PrepareForQuery may use (0 = all cores; default 1). The kd-tree balances disjoint
  // subtrees concurrently; the post-build order is the same for any value (kdtree.h).
  void set_build_threads(int threads) { build_threads_ = threads; }
  int build_threads() const { return build_threads_; }

  // Builds the acceleration structure once, reordering the photons in place (§2.2). Throws
  // std::length_error beyond kMaxPhotons.
  void PrepareForQuery() {
    if (photons_.size() > kMaxPhotons) throw std::length_error("PhotonMap: too many photons");
    photons_.shrink_to_fit();  // the walk is over: drop the dynamic array's growth slack
    if (!photons_.empty()) Build();
    prepared_ = true;
  }
  bool prepared() const { return prepared_; }

  // As PrepareForQuery, and reports where each photon came from: (*original_index)[i] is the
  // insertion index of post-build photon i, so that attributes kept outside the 18 bytes
  // (light id for PhotonDirect §4.2.3, origin for occlusion testing §4.1.1) can follow the
  // build, and are only paid for when an estimator needs them. Both builds order photons by
  // position alone, so the index rides in the power bytes during the build (no extra pass).
  void PrepareForQuery(std::vector<uint32_t>* original_index) {
    std::vector<std::array<uint8_t, 4>> power(photons_.size());
    for (std::size_t i = 0; i < photons_.size(); ++i) {
      for (int b = 0; b < 4; ++b) power[i][b] = photons_[i].rgbe[b];
      const uint32_t index = uint32_t(i);
      for (int b = 0; b < 4; ++b) photons_[i].rgbe[b] = uint8_t(index >> (8 * b));
    }
    PrepareForQuery();
    original_index->resize(photons_.size());
    for (std::size_t i = 0; i < photons_.size(); ++i) {
      uint32_t index = 0;
      for (int b = 0; b < 4; ++b) index |= uint32_t(photons_[i].rgbe[b]) << (8 * b);
      (*original_index)[i] = index;
      for (int b = 0; b < 4; ++b) photons_[i].rgbe[b] = power[index][b];
    }
  }

  // The k nearest photons around x within max_radius, into `nearest` (see the semantics at
  // the top of this file). Throws std::logic_error if the map is not prepared.
  void Query(const Vec3& x, int k, float max_radius, NearestPhotons& nearest,
             const PhotonFilter* filter = nullptr) const {
    nearest.Reset(k, max_radius);
    if (!prepared_) throw std::logic_error("PhotonMap::Query before PrepareForQuery");
    if (nearest.k() == 0 || photons_.empty() || !IsFinite(x) || !(nearest.BoundSquared() > 0.0f)) return;
    DoQuery(x, nearest, filter);
  }

  // Exact k-NN with a guessed radius (e.g. the previous query's k-th distance, slightly
  // enlarged, for a neighbouring pixel): searches the open ball of radius
  // min(hint_radius, max_radius) first. If that ball holds k accepted photons they are the k
  // nearest overall (every photon outside lies at ≥ hint_radius, beyond all of them), so the
  // result is exactly Query's; otherwise it searches again with max_radius. A good hint culls
  // most of the tree from the start and spares the heap the photons that would enter it only
  // to be evicted. Returns true iff the hint sufficed.
  //
  // The first pass goes through DoQueryBall, which a map may implement without a heap (the
  // bucket kd-tree does: BallCollector). Its result is the same set as Query's up to ties at
  // the k-th distance, the farthest entry first, but the others may come in another order
  // than a plain Query's (so a sum over them may differ in the last bits).
  bool QueryWithHint(const Vec3& x, int k, float max_radius, float hint_radius, NearestPhotons& nearest,
                     const PhotonFilter* filter = nullptr) const {
    if (hint_radius > 0.0f && hint_radius < max_radius) {
      nearest.Reset(k, hint_radius);
      if (!prepared_) throw std::logic_error("PhotonMap::QueryWithHint before PrepareForQuery");
      if (nearest.k() == 0) return true;  // the empty result is complete
      if (!photons_.empty() && IsFinite(x) && nearest.BoundSquared() > 0.0f &&
          DoQueryBall(x, nearest, filter))
        return true;
    }
    Query(x, k, max_radius, nearest, filter);
    return false;
  }

  // A range query: every accepted photon in the open ball of radius `radius` around x, into
  // `nearest`, the farthest first (no k: the pass estimate of progressive photon mapping, Knaus &
  // Zwicker 2011, §4, sums all photons within the pass's radius). Written once for every structure
  // on top of Query: a k-NN query whose heap does not fill returns exactly the ball's candidates
  // (its bound stays radius² until it is full), so it runs with k = max(64, the previous k) and
  // again with 4k until the heap is not full or k covers the whole map. `nearest` keeps its k, so
  // the next query of a thread starts at the size the last one needed.
  void QueryRadius(const Vec3& x, float radius, NearestPhotons& nearest,
                   const PhotonFilter* filter = nullptr) const {
    std::size_t k = std::max<std::size_t>(64, nearest.k());
    for (;;) {
      const std::size_t kk = std::min(k, std::max<std::size_t>(photons_.size(), 1));
      Query(x, int(kk), radius, nearest, filter);
      if (!nearest.full() || kk >= photons_.size()) return;
      k *= 4;
    }
  }

  std::size_t size() const { return photons_.size(); }
  bool empty() const { return photons_.empty(); }
  // Post-build order once prepared.
  const Photon& photon(std::size_t i) const { return photons_[i]; }
  std::span<const Photon> photons() const { return photons_; }

  // Bytes held by the map (photon array and acceleration structure). Per-thread query
  // scratch lives in NearestPhotons and is not included.
  virtual std::size_t MemoryBytes() const { return photons_.capacity() * sizeof(Photon); }

  // Photon indices are 32-bit and the kd-tree's node numbers 2i+1 must fit too.
  static constexpr std::size_t kMaxPhotons = (std::size_t(1) << 31) - 1;

 protected:
  // Called by PrepareForQuery with at least one photon.
  virtual void Build() = 0;
  // Called by Query with k ≥ 1, a finite x, a non-empty map and `nearest` already Reset.
  virtual void DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const = 0;
  // The first pass of QueryWithHint, with the same preconditions as DoQuery (`nearest` Reset
  // to k and the hint radius): returns true iff the ball holds k accepted photons, which are
  // then the result. The default is the heap query; a map may override it (see
  // BallCollector).
  virtual bool DoQueryBall(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const {
    DoQuery(x, nearest, filter);
    return nearest.full();
  }

  std::vector<Photon> photons_;  // one dynamic array (§2.2); reordered by Build
  bool prepared_ = false;
  int build_threads_ = 1;

 private:
  static void CheckPosition(const Photon& p) {
    if (!IsFinite(p.Position())) throw std::invalid_argument("PhotonMap: non-finite photon position");
  }
};

}  // namespace pf
