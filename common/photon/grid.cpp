#include "common/photon/grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace pf {
namespace {

// Absolute ceiling on voxels, whatever the options say: voxel indices are 32-bit.
constexpr double kMaxVoxelsHard = double(1u << 30);

}  // namespace

int32_t GridPhotonMap::AxisCoord(int axis, float v) const {
  const std::vector<float>& planes = planes_[axis];
  const int32_t k = res_[axis];
  const float t = (v - planes[0]) * inv_cell_;
  int32_t i = t > 0.0f ? (t < float(k) ? int32_t(t) : k - 1) : 0;
  // The multiply above may round across a plane; the table is the ground truth, so that
  // planes[i] ≤ v < planes[i + 1] holds for every photon (see "Exactness" in grid.h).
  while (i > 0 && v < planes[i]) --i;
  while (i + 1 < k && v >= planes[i + 1]) ++i;
  return i;
}

void GridPhotonMap::SetResolution(const Bounds3& box, double h) {
  const Vec3 extent = box.Diagonal();
  const float max_extent = MaxComponent(extent);
  cell_ = float(h);
  inv_cell_ = 1.0f / cell_;
  for (int a = 0; a < 3; ++a) {
    // Flat axes (planar scenes, a single photon) get one voxel.
    const bool flat = !(extent[a] > max_extent * 1e-6f);
    const double k = flat ? 1.0 : std::clamp(std::ceil(double(extent[a]) / h), 1.0, kMaxVoxelsHard);
    res_[a] = int(k);
    std::vector<float>& planes = planes_[a];
    planes.resize(std::size_t(res_[a]) + 1);
    for (int i = 0; i <= res_[a]; ++i) planes[i] = box.lo[a] + float(i) * cell_;
    planes[0] = box.lo[a];
    planes[res_[a]] = std::max(planes[res_[a]], box.hi[a]);  // the grid covers every photon
  }
}

double GridPhotonMap::CountPhotons(std::vector<uint32_t>& counts) const {
  counts.assign(std::size_t(res_[0]) * std::size_t(res_[1]) * std::size_t(res_[2]), 0);
  std::size_t occupied = 0;
  for (const Photon& p : photons_) occupied += counts[VoxelOf(p)]++ == 0 ? 1 : 0;
  return double(photons_.size()) / double(std::max<std::size_t>(occupied, 1));
}

void GridPhotonMap::Build() {
  const std::size_t n = photons_.size();
  Bounds3 box;
  for (const Photon& p : photons_) box.Extend(p.Position());
  const Vec3 extent = box.Diagonal();
  const float max_extent = MaxComponent(extent);

  // Target photons per occupied voxel (see the resolution rule in grid.h).
  const double k = std::max(options_.expected_k, 1);
  double t = options_.photons_per_voxel > 0.0f ? double(options_.photons_per_voxel) : 2.2 * std::sqrt(k);
  t = std::max(t, 1.0);
  target_ = float(t);
  const double cap = std::clamp(std::floor(double(n) * options_.max_voxels_per_photon), 1.0, kMaxVoxelsHard);

  double volume = 1.0;
  int dims = 0;
  for (int a = 0; a < 3; ++a) {
    if (extent[a] > max_extent * 1e-6f) {
      volume *= extent[a];
      ++dims;
    }
  }
  auto voxels = [&] { return double(res_[0]) * double(res_[1]) * double(res_[2]); };
  // Voxel edge h for a wish, enlarged until the voxel count is within the cap.
  auto fit = [&](double h) {
    SetResolution(box, h);
    while (voxels() > cap) {
      h *= std::pow(voxels() / cap, 1.0 / std::max(dims, 1)) * 1.001;
      SetResolution(box, h);
    }
    return h;
  };

  std::vector<uint32_t> counts;
  double m = 0.0;
  if (dims == 0) {
    // All photons at one point: one voxel.
    fit(1.0);
    m = CountPhotons(counts);
  } else {
    // Start as if the photons filled the box's volume, then correct with the measured
    // photons per occupied voxel: first assuming surfaces (m ∝ h²), then with the measured
    // local dimension.
    double h = fit(std::pow(volume * t / double(n), 1.0 / dims));
    m = CountPhotons(counts);
    double prev_h = 0.0, prev_m = 0.0;
    for (int pass = 0; pass < 3; ++pass) {
      if (std::abs(std::log(m / t)) < std::log(1.25)) break;
      double dim = 2.0;
      if (prev_h > 0.0 && prev_h != h && prev_m > 0.0)
        dim = std::clamp(std::log(m / prev_m) / std::log(h / prev_h), 1.0, 3.0);
      const double next_h = fit(h * std::pow(t / m, 1.0 / dim));
      if (next_h == h) break;  // held at the voxel cap
      prev_h = h;
      prev_m = m;
      h = next_h;
      m = CountPhotons(counts);
    }
  }
  achieved_ = float(m);
  for (auto& planes : planes_) planes.shrink_to_fit();

  // Voxel → first photon (prefix sums of the counts), then the in-place sort by voxel.
  const std::size_t v_count = counts.size();
  first_.assign(v_count + 1, 0);
  for (std::size_t v = 0; v < v_count; ++v) first_[v + 1] = first_[v] + counts[v];
  first_.shrink_to_fit();
  counts.clear();
  counts.shrink_to_fit();
  SortByVoxel();
}

// An in-place counting sort ("American flag" permutation): a cursor per bucket walks its
// run, and every swap moves one photon into its bucket's run for good, so each pass is O(N)
// with no second photon array (§2.4: the grid is built in place). Done most-significant
// digit first — z slabs, then the voxels of each slab — because a single pass over millions
// of buckets would make almost every swap a cache miss; with a few hundred slab cursors the
// writes stream, and a slab's photons fit in cache for the second pass.
void GridPhotonMap::SortByVoxel() {
  const std::size_t slab = std::size_t(res_[0]) * std::size_t(res_[1]);
  std::vector<uint32_t> next(std::max(std::size_t(res_[2]), slab));
  for (int z = 0; z < res_[2]; ++z) next[z] = first_[std::size_t(z) * slab];
  for (int z = 0; z < res_[2]; ++z) {
    const uint32_t end = first_[std::size_t(z + 1) * slab];
    while (next[z] < end) {
      const uint32_t i = next[z];
      const int32_t w = AxisCoord(2, photons_[i].position[2]);
      if (w == z) {
        ++next[z];
      } else {
        std::swap(photons_[i], photons_[next[w]++]);  // w > z: earlier slabs are complete
      }
    }
  }
  for (int z = 0; z < res_[2]; ++z) {
    const std::size_t base = std::size_t(z) * slab;
    if (first_[base] == first_[base + slab]) continue;  // empty slab
    std::copy(first_.begin() + std::ptrdiff_t(base), first_.begin() + std::ptrdiff_t(base + slab),
              next.begin());
    for (std::size_t v = 0; v < slab; ++v) {
      const uint32_t end = first_[base + v + 1];
      while (next[v] < end) {
        const uint32_t i = next[v];
        const std::size_t w = VoxelOf(photons_[i]) - base;
        if (w == v) {
          ++next[v];
        } else {
          std::swap(photons_[i], photons_[next[w]++]);
        }
      }
    }
  }
}

std::size_t GridPhotonMap::MemoryBytes() const {
  std::size_t bytes = PhotonMap::MemoryBytes() + first_.capacity() * sizeof(uint32_t);
  for (const auto& planes : planes_) bytes += planes.capacity() * sizeof(float);
  return bytes;
}

void GridPhotonMap::DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const {
  NearestPhotons::GridScratch& scratch = nearest.grid_;
  // A previous query that was left by an exception (from the filter) may have left tags.
  for (const auto& c : scratch.fill) scratch.visited[uint32_t(c[3]) >> 6] = 0;
  scratch.fill.clear();
  const std::size_t words = (voxel_count() + 63) / 64;
  if (scratch.visited.size() < words) scratch.visited.resize(words, 0);
  uint64_t* visited = scratch.visited.data();
  auto test_and_set = [visited](uint32_t v) {
    const uint64_t bit = uint64_t(1) << (v & 63);
    const bool was = (visited[v >> 6] & bit) != 0;
    visited[v >> 6] |= bit;
    return was;
  };

  const float q[3] = {x.x, x.y, x.z};
  const std::size_t stride[3] = {1, std::size_t(res_[0]), std::size_t(res_[0]) * std::size_t(res_[1])};
  float bound2 = nearest.BoundSquared();

  // Wald 1999, §2.4: the seed voxel holds x (or, outside the grid, the grid's point nearest
  // to x), so its photons are likely candidates and the bound shrinks fast.
  {
    const int32_t i = AxisCoord(0, x.x), j = AxisCoord(1, x.y), k = AxisCoord(2, x.z);
    const uint32_t v = uint32_t(VoxelIndex({i, j, k}));
    test_and_set(v);
    scratch.fill.push_back({i, j, k, int32_t(v)});
  }
  // Breadth-first seed fill: voxels are tagged when queued, and re-tested when dequeued
  // because the bound may have shrunk meanwhile.
  for (std::size_t head = 0; head < scratch.fill.size(); ++head) {
    const std::array<int32_t, 4> c = scratch.fill[head];
    float term[3];
    for (int a = 0; a < 3; ++a) term[a] = AxisTerm(a, c[a], q[a]);
    if (!((term[0] + term[1]) + term[2] < bound2)) continue;

    const uint32_t v = uint32_t(c[3]);
    for (uint32_t i = first_[v], end = first_[v + 1]; i < end; ++i) {
      const Photon& p = photons_[i];
      const float d2 = DistanceSquared(p, x);
      if (d2 < bound2 && (filter == nullptr || filter->Accept(p, i))) {
        nearest.Insert(i, d2);
        bound2 = nearest.BoundSquared();
      }
    }

    for (int a = 0; a < 3; ++a) {
      for (int step = -1; step <= 1; step += 2) {
        const int32_t ca = c[a] + step;
        if (ca < 0 || ca >= res_[a]) continue;
        const uint32_t nv = step < 0 ? uint32_t(v - stride[a]) : uint32_t(v + stride[a]);
        if (visited[nv >> 6] & (uint64_t(1) << (nv & 63))) continue;
        float t[3] = {term[0], term[1], term[2]};
        t[a] = AxisTerm(a, ca, q[a]);
        // Same summation order as DistanceSquared, so the bound stays exact (grid.h).
        if (!((t[0] + t[1]) + t[2] < bound2)) continue;
        test_and_set(nv);
        std::array<int32_t, 4> next = c;
        next[a] = ca;
        next[3] = int32_t(nv);
        scratch.fill.push_back(next);
      }
    }
  }

  for (const auto& c : scratch.fill) visited[uint32_t(c[3]) >> 6] = 0;
  scratch.fill.clear();
}

}  // namespace pf
