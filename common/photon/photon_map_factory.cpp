#include "common/photon/photon_map_factory.h"

#include <cmath>

#include "common/core/error.h"
#include "common/photon/bucket_kdtree.h"
#include "common/photon/grid.h"
#include "common/photon/kdtree.h"

namespace pf {
namespace {

std::unique_ptr<PhotonMap> BuildKdTree(const PhotonMapOptions& o) {
  return std::make_unique<KdTree>(o.kd_split_rule, o.kd_culling);
}

std::unique_ptr<PhotonMap> BuildGrid(const PhotonMapOptions& o) {
  // grid.h: the voxel size comes from expected_k unless photons_per_voxel is given.
  if (o.grid.expected_k < 1)
    throw InputError("structure grid: expected_k (the k of the queries) must be >= 1, not " +
                     std::to_string(o.grid.expected_k));
  if (!(o.grid.photons_per_voxel >= 0.0f) || !std::isfinite(o.grid.photons_per_voxel))
    throw InputError("structure grid: photons_per_voxel must be >= 0 (0 = from expected_k)");
  if (!(o.grid.max_voxels_per_photon > 0.0) || !std::isfinite(o.grid.max_voxels_per_photon))
    throw InputError("structure grid: max_voxels_per_photon must be > 0");
  return std::make_unique<GridPhotonMap>(o.grid);
}

std::unique_ptr<PhotonMap> BuildBucketKdTree(const PhotonMapOptions& o) {
  // bucket_kdtree.h: a bucket is tested in SIMD steps of at most 64 photons.
  if (o.bucket.leaf_size < 1 || o.bucket.leaf_size > 64)
    throw InputError("structure bucket: leaf_size must be in [1, 64], not " +
                     std::to_string(o.bucket.leaf_size));
  return std::make_unique<BucketKdTree>(o.bucket);
}

}  // namespace

const NamedRegistry<PhotonMapStructure>& PhotonMapStructures() {
  static const NamedRegistry<PhotonMapStructure> registry(
      "photon-map structure",
      {{.name = "kdtree",
        .kind = PhotonMapKind::kKdTree,
        .serializable = true,
        .settings = {"kd-split"},
        .build = BuildKdTree},
       {.name = "grid", .kind = PhotonMapKind::kGrid, .serializable = false, .build = BuildGrid},
       {.name = "bucket",
        .kind = PhotonMapKind::kBucketKdTree,
        .serializable = false,
        .build = BuildBucketKdTree}});
  return registry;
}

std::unique_ptr<PhotonMap> MakePhotonMap(PhotonMapKind kind, const PhotonMapOptions& options) {
  return PhotonMapStructures().FindKind(kind).build(options);
}

}  // namespace pf
