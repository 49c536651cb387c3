#pragma once
// The grid photon map of Wald 1999, §2.4: a regular grid of Kx×Ky×Kz cubic voxels over the
// photons' bounding box; the photons are sorted by voxel in place (a counting sort in two
// passes, z slabs first, then the voxels of each slab: O(N), temporary memory only for the
// per-voxel counts), and each voxel is the offset of its first photon (its photons run to
// the next voxel's first photon). Memory: 18 bytes per photon + 4 bytes per voxel.
//
// Resolution rule (the thesis leaves "K as a function of N and k" open, §2.4). We choose the
// voxel edge h so that an *occupied* voxel holds about t photons:
//   t = GridOptions::photons_per_voxel, or by default t = 2.2·√k with k = expected_k (≥ 1).
//     A cost model (distance tests ∝ σ(2r + h)² for photons of surface density σ and a
//     k-NN radius r with πr²σ = k, plus voxel visits ∝ (2r/h + 1)³) has its minimum near
//     h ≈ r for k ≈ 50 and towards smaller h/r for larger k; that is t ≈ 7, 16, 40 for
//     k = 10, 50, 500, which 2.2·√k follows. (Benchmark: bench/photon_map_bench.cpp.)
//   Start from the h that gives t photons per voxel if the photons filled the box's volume,
//   then count the photons per occupied voxel m(h) (one O(N) pass each) and correct h:
//   first assuming the photons lie on surfaces (m ∝ h²), then with the dimension D
//   measured from the last two passes (m ∝ h^D, D clamped to [1, 3]), at most 4 passes,
//   stopping once m is within 25% of t. Axes whose extent is ~0 get one voxel (planar
//   scenes). Per-axis resolutions K = ⌈extent / h⌉ (§2.4, footnote 3: non-cubic scenes get
//   different resolutions per axis).
//   The voxel count is capped at max(1, N · max_voxels_per_photon) (default: ≤ 1 voxel per
//   photon, i.e. ≤ 4 bytes per photon of offsets) by enlarging h.
//
// Query (§2.4): start at the voxel containing x (clamped to the grid for points outside
// it), process its photons, then visit neighbouring voxels in a breadth-first 3-D seed fill
// across voxel faces, entering a voxel only if its minimum squared distance to x is below the
// heap's current bound (max_radius² until k photons are found). Face neighbours suffice: the
// voxels meeting the open search ball (intersected with the grid's box) are face-connected.
// Visited voxels are tagged in a bitmap that belongs to the caller's NearestPhotons, not to
// the map, so const queries from many threads do not interfere (the thesis keeps one tag per
// voxel in the map and a global query counter, which is not thread-safe). The bits set by
// a query are cleared at its end through its list of visited voxels.
//
// Exactness: voxel boundaries are a per-axis table of planes, and photons are binned against
// that same table, so a photon's DistanceSquared is never below its voxel's computed minimum
// distance (float rounding is monotonic). The grid therefore finds exactly the brute-force
// distance multiset.

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/photon/photon_map.h"

namespace pf {

class GridPhotonMap final : public PhotonMap {
 public:
  explicit GridPhotonMap(const GridOptions& options = {}) : options_(options) {}

  const GridOptions& options() const { return options_; }
  // Kx, Ky, Kz (all 0 before the first build or for an empty map).
  std::array<int, 3> resolution() const { return res_; }
  float cell_size() const { return cell_; }
  std::size_t voxel_count() const { return first_.empty() ? 0 : first_.size() - 1; }
  // Photons [first, last) of voxel (i, j, k) in post-build order.
  std::pair<uint32_t, uint32_t> VoxelPhotons(int i, int j, int k) const {
    const std::size_t v = VoxelIndex({i, j, k});
    return {first_[v], first_[v + 1]};
  }
  // The photons-per-occupied-voxel target t the build aimed for, and what it achieved.
  float target_photons_per_voxel() const { return target_; }
  float photons_per_occupied_voxel() const { return achieved_; }

  std::size_t MemoryBytes() const override;

 protected:
  void Build() override;
  void DoQuery(const Vec3& x, NearestPhotons& nearest, const PhotonFilter* filter) const override;

 private:
  using Coord = std::array<int32_t, 3>;

  std::size_t VoxelIndex(const Coord& c) const {
    return (std::size_t(c[2]) * std::size_t(res_[1]) + std::size_t(c[1])) * std::size_t(res_[0]) +
           std::size_t(c[0]);
  }
  // Voxel coordinate of v along `axis`, clamped to the grid and consistent with planes_.
  int32_t AxisCoord(int axis, float v) const;
  std::size_t VoxelOf(const Photon& p) const {
    return VoxelIndex(
        {AxisCoord(0, p.position[0]), AxisCoord(1, p.position[1]), AxisCoord(2, p.position[2])});
  }
  // Squared distance from x_a to the slab [planes_[a][i], planes_[a][i + 1]].
  float AxisTerm(int axis, int32_t i, float xa) const {
    const float below = planes_[axis][i] - xa;
    const float above = xa - planes_[axis][i + 1];
    const float d = below > 0.0f ? below : (above > 0.0f ? above : 0.0f);
    return d * d;
  }
  // Sets the resolution and planes for voxel edge h; returns false if over the cap.
  void SetResolution(const Bounds3& box, double h);
  // Counts photons per voxel; returns photons per occupied voxel.
  double CountPhotons(std::vector<uint32_t>& counts) const;
  void SortByVoxel();

  GridOptions options_;
  std::array<int, 3> res_{};
  float cell_ = 0.0f;
  float inv_cell_ = 0.0f;
  std::array<std::vector<float>, 3> planes_;  // K + 1 boundary positions per axis
  std::vector<uint32_t> first_;               // voxel → first photon; V + 1 entries
  float target_ = 0.0f;
  float achieved_ = 0.0f;
};

}  // namespace pf
