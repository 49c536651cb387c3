#pragma once
// The last step of every photon-map build, shared by the one-process build (PhotonMaps::Build)
// and the maps assembled from pieces traced elsewhere (AssemblePhotonMaps, photon_chunk.h): the
// lists of photons in photon order go into the maps of `options`, which are then built. One code
// path, so a distributed map is the local one bit for bit (tests/common/photon_chunk_test.cpp).

#include <array>
#include <functional>
#include <initializer_list>
#include <memory>
#include <vector>

#include "common/photon/photon_maps.h"

namespace pf {

// One map of `options` holding `photons` in their order (the order decides the balanced tree),
// built. With keep_light_ids / keep_origins, `attributes_in_order` gives the attributes of
// `photons` in the same order (called once the photons are freed, so both never peak together);
// they are stored in the map's post-build order in `attributes`.
std::unique_ptr<PhotonMap> BuildPhotonMap(const PhotonMapsOptions& options, std::vector<Photon> photons,
                                          const std::function<PhotonAttributes()>& attributes_in_order,
                                          PhotonAttributes* attributes);

// Fills `maps` (its global, direct and caustic maps and their stats.stored_* and build_seconds)
// as `options` says: the global map from the direct and indirect lists, or from the indirect list
// with separate_direct (then the direct map, if direct_map, concurrently); the caustic map if
// `caustic` (else its `counts` photons are dropped, with a warning). `fill(kinds, attributes)`
// builds one map from the concatenation of those lists (BuildPhotonMap); `counts` are the
// photons of each list, indexed by PhotonKind.
using FillPhotonMap =
    std::function<std::unique_ptr<PhotonMap>(std::initializer_list<PhotonKind> kinds, PhotonAttributes*)>;
void FillPhotonMaps(const PhotonMapsOptions& options, bool caustic, const std::array<uint64_t, 3>& counts,
                    const FillPhotonMap& fill, PhotonMaps* maps);

}  // namespace pf
