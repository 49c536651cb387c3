#include "common/photon/photon_map.h"

#include "common/photon/bucket_kdtree.h"
#include "common/photon/grid.h"
#include "common/photon/kdtree.h"

namespace pf {

std::unique_ptr<PhotonMap> MakePhotonMap(PhotonMapKind kind, const PhotonMapOptions& options) {
  switch (kind) {
    case PhotonMapKind::kKdTree:
      return std::make_unique<KdTree>(options.kd_split_rule, options.kd_culling);
    case PhotonMapKind::kGrid:
      return std::make_unique<GridPhotonMap>(options.grid);
    case PhotonMapKind::kBucketKdTree:
      return std::make_unique<BucketKdTree>(options.bucket);
  }
  return nullptr;
}

}  // namespace pf
