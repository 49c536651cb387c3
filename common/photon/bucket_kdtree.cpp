#include "common/photon/bucket_kdtree.h"

#include <immintrin.h>

#include <algorithm>
#include <array>
#include <bit>
#include <limits>
#include <stdexcept>

namespace pf {
namespace {

// Deeper than any median tree (2^31 photons / 1 per leaf); the midpoint rule falls back to
// median splits below this depth, so a traversal stack of kMaxDepth + 1 entries suffices.
constexpr int kMaxDepth = 48;
// Readable floats past the last photon: a bucket's last 8-wide load may run over its end.
constexpr std::size_t kPad = 8;
// See "Exactness" in bucket_kdtree.h: 1 ± 2^-16 is far beyond any FMA-versus-separate
// rounding difference of a sum of three non-negative products (a few ulp, 2^-23 each).
constexpr float kSelectGrow = 1.0f + 0x1p-16f;
constexpr float kCullShrink = 1.0f - 0x1p-16f;

// Build item: a photon's position and its insertion index (16 bytes: cheaper to move
// around during the partitioning than the 18-byte photon).
struct Item {
  float p[3];
  uint32_t index;
};

class Builder {
 public:
  Builder(std::vector<Item>& items, const BucketKdOptions& options, std::vector<BucketKdTree::Node>& nodes)
      : items_(items), options_(options), nodes_(nodes) {}

  void Build(uint32_t begin, uint32_t end, int depth) {
    max_depth_ = std::max(max_depth_, depth);
    const uint32_t self = uint32_t(nodes_.size());
    nodes_.push_back({});
    const uint32_t count = end - begin;
    if (count <= uint32_t(options_.leaf_size)) {
      nodes_[self] = {std::bit_cast<float>(begin), 3u | (count << 2)};
      ++leaves_;
      return;
    }
    // Bounding box of the node's photons: the widest extent is the split axis.
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) lo[a] = hi[a] = items_[begin].p[a];
    for (uint32_t i = begin + 1; i < end; ++i) {
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], items_[i].p[a]);
        hi[a] = std::max(hi[a], items_[i].p[a]);
      }
    }
    const float ex = hi[0] - lo[0], ey = hi[1] - lo[1], ez = hi[2] - lo[2];
    const int axis = ex >= ey ? (ex >= ez ? 0 : 2) : (ey >= ez ? 1 : 2);
    Item* const first = items_.data() + begin;
    Item* const last = items_.data() + end;
    uint32_t mid = 0;
    float split = 0.0f;
    if (options_.split == BucketSplit::kMidpoint && depth < kMaxDepth - 8 && hi[axis] > lo[axis]) {
      // Sliding midpoint: photons < split go left, ≥ split right; if a side would be
      // empty the plane slides to the nearest photon, which then sits alone on that side.
      split = lo[axis] + 0.5f * (hi[axis] - lo[axis]);
      Item* cut = std::partition(first, last, [axis, split](const Item& it) { return it.p[axis] < split; });
      if (cut == first) {
        // Every photon ≥ split: move the smallest to the front, split at it.
        std::nth_element(first, first, last,
                         [axis](const Item& a, const Item& b) { return a.p[axis] < b.p[axis]; });
        cut = first + 1;
        split = first->p[axis];
      } else if (cut == last) {
        std::nth_element(first, last - 1, last,
                         [axis](const Item& a, const Item& b) { return a.p[axis] < b.p[axis]; });
        cut = last - 1;
        split = cut->p[axis];
      }
      mid = begin + uint32_t(cut - first);
    } else {
      mid = begin + count / 2;
      std::nth_element(first, items_.data() + mid, last,
                       [axis](const Item& a, const Item& b) { return a.p[axis] < b.p[axis]; });
      split = items_[mid].p[axis];
    }
    // Left [begin, mid) ≤ split ≤ right [mid, end) on `axis`.
    Build(begin, mid, depth + 1);
    const uint32_t right = uint32_t(nodes_.size());
    Build(mid, end, depth + 1);
    nodes_[self] = {split, uint32_t(axis) | (right << 2)};
  }

  std::size_t leaves() const { return leaves_; }
  int max_depth() const { return max_depth_; }

 private:
  std::vector<Item>& items_;
  const BucketKdOptions& options_;
  std::vector<BucketKdTree::Node>& nodes_;
  std::size_t leaves_ = 0;
  int max_depth_ = 0;
};

// Candidate sinks of Search (bucket_kdtree_search.inc).
// HeapSink: the bounded max-heap of Query (Wald 1999, §2.3.2): the bound tightens at every
// insert once the heap is full.
struct HeapSink {
  NearestPhotons& nearest;
  float Bound() const { return nearest.BoundSquared(); }
  float Add(uint32_t i, float d2) {
    nearest.Insert(i, d2);
    return nearest.BoundSquared();
  }
};

// BallSink: QueryWithHint's first pass: every candidate of the hint ball into a flat
// buffer, the k nearest selected once at the end (BallCollector, photon_map.h).
using BallSink = BallCollector;

namespace sse {

struct QueryLanes {
  explicit QueryLanes(const Vec3& x) : qx(_mm_set1_ps(x.x)), qy(_mm_set1_ps(x.y)), qz(_mm_set1_ps(x.z)) {}
  uint32_t Mask4(const float* x, const float* y, const float* z, __m128 bound2) const {
    const __m128 dx = _mm_sub_ps(_mm_loadu_ps(x), qx);
    const __m128 dy = _mm_sub_ps(_mm_loadu_ps(y), qy);
    const __m128 dz = _mm_sub_ps(_mm_loadu_ps(z), qz);
    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)), _mm_mul_ps(dz, dz));
    return uint32_t(_mm_movemask_ps(_mm_cmplt_ps(d2, bound2)));
  }
  uint32_t Mask8(const float* x, const float* y, const float* z, float bound2) const {
    const __m128 b = _mm_set1_ps(bound2);
    return Mask4(x, y, z, b) | (Mask4(x + 4, y + 4, z + 4, b) << 4);
  }
  __m128 qx, qy, qz;
};

#include "common/photon/bucket_kdtree_search.inc"

}  // namespace sse

#pragma GCC push_options
#pragma GCC target("avx2")
namespace avx2 {

struct QueryLanes {
  explicit QueryLanes(const Vec3& x)
      : qx(_mm256_set1_ps(x.x)), qy(_mm256_set1_ps(x.y)), qz(_mm256_set1_ps(x.z)) {}
  uint32_t Mask8(const float* x, const float* y, const float* z, float bound2) const {
    const __m256 dx = _mm256_sub_ps(_mm256_loadu_ps(x), qx);
    const __m256 dy = _mm256_sub_ps(_mm256_loadu_ps(y), qy);
    const __m256 dz = _mm256_sub_ps(_mm256_loadu_ps(z), qz);
    const __m256 d2 =
        _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), _mm256_mul_ps(dz, dz));
    return uint32_t(_mm256_movemask_ps(_mm256_cmp_ps(d2, _mm256_set1_ps(bound2), _CMP_LT_OQ)));
  }
  __m256 qx, qy, qz;
};

#include "common/photon/bucket_kdtree_search.inc"

}  // namespace avx2
#pragma GCC pop_options

}  // namespace

BucketKdTree::BucketKdTree(const BucketKdOptions& options) : options_(options) {
  if (options_.leaf_size < 1 || options_.leaf_size > 64)
    throw std::invalid_argument("BucketKdTree: leaf_size must be in [1, 64]");
  avx2_ = options_.allow_avx2 && __builtin_cpu_supports("avx2");
}

const char* BucketKdTree::simd() const {
  return avx2_ ? "avx2" : "sse";
}

std::size_t BucketKdTree::MemoryBytes() const {
  return PhotonMap::MemoryBytes() + nodes_.capacity() * sizeof(Node) +
         (xs_.capacity() + ys_.capacity() + zs_.capacity()) * sizeof(float);
}

void BucketKdTree::Build() {
  const std::size_t n = photons_.size();
  std::vector<Item> items(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Photon& p = photons_[i];
    items[i] = {{p.position[0], p.position[1], p.position[2]}, uint32_t(i)};
  }
  nodes_.clear();
  nodes_.reserve(4 * n / std::size_t(options_.leaf_size) + 2);
  Builder builder(items, options_, nodes_);
  builder.Build(0, uint32_t(n), 0);
  nodes_.shrink_to_fit();
  leaves_ = builder.leaves();
  depth_ = builder.max_depth();

  // Post-build order: the photons of each bucket contiguous, in the order of the items.
  {
    std::vector<Photon> ordered(n);
    for (std::size_t i = 0; i < n; ++i) ordered[i] = photons_[items[i].index];
    photons_.swap(ordered);
  }
  xs_.assign(n + kPad, 0.0f);
  ys_.assign(n + kPad, 0.0f);
  zs_.assign(n + kPad, 0.0f);
  for (std::size_t i = 0; i < n; ++i) {
    xs_[i] = items[i].p[0];
    ys_[i] = items[i].p[1];
    zs_[i] = items[i].p[2];
  }
}

void BucketKdTree::DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const {
  if (avx2_) {
    avx2::SearchHeap(nodes_.data(), xs_.data(), ys_.data(), zs_.data(), photons_.data(), x, nearest, filter);
  } else {
    sse::SearchHeap(nodes_.data(), xs_.data(), ys_.data(), zs_.data(), photons_.data(), x, nearest, filter);
  }
}

bool BucketKdTree::DoQueryBall(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const {
  if (avx2_)
    return avx2::SearchBall(nodes_.data(), xs_.data(), ys_.data(), zs_.data(), photons_.data(), x, nearest,
                            filter);
  return sse::SearchBall(nodes_.data(), xs_.data(), ys_.data(), zs_.data(), photons_.data(), x, nearest,
                         filter);
}

}  // namespace pf
