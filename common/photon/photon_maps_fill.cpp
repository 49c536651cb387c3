#include "common/photon/photon_maps_fill.h"

#include <spdlog/spdlog.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <chrono>

#include "common/photon/photon_map_factory.h"

namespace pf {

std::unique_ptr<PhotonMap> BuildPhotonMap(const PhotonMapsOptions& o, std::vector<Photon> photons,
                                          const std::function<PhotonAttributes()>& attributes_in_order,
                                          PhotonAttributes* attributes) {
  auto map = MakePhotonMap(o.kind, o.structure);
  map->set_build_threads(o.tracing.threads);
  const size_t n = photons.size();
  map->AddPhotons(photons);
  std::vector<Photon>().swap(photons);
  if (!o.keep_light_ids && !o.keep_origins) {
    map->PrepareForQuery();
    return map;
  }
  std::vector<uint32_t> original;
  map->PrepareForQuery(&original);
  const PhotonAttributes in_order = attributes_in_order();
  if (o.keep_light_ids) attributes->light.resize(n);
  if (o.keep_origins) attributes->origin.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if (o.keep_light_ids) attributes->light[i] = in_order.light[original[i]];
    if (o.keep_origins) attributes->origin[i] = in_order.origin[original[i]];
  }
  return map;
}

void FillPhotonMaps(const PhotonMapsOptions& options, bool caustic, const std::array<uint64_t, 3>& counts,
                    const FillPhotonMap& fill, PhotonMaps* maps) {
  const auto t0 = std::chrono::steady_clock::now();
  if (options.separate_direct) {
    // Two independent maps: built concurrently, so that the serial top split of one kd-tree
    // overlaps with the other's build (each map is the same as when built alone).
    tbb::task_arena arena(options.tracing.threads > 0 ? options.tracing.threads : tbb::task_arena::automatic);
    arena.execute([&] {
      tbb::parallel_invoke([&] { maps->global = fill({PhotonKind::kIndirect}, &maps->global_attributes); },
                           [&] {
                             if (options.direct_map)
                               maps->direct = fill({PhotonKind::kDirect}, &maps->direct_attributes);
                           });
    });
  } else {
    maps->global = fill({PhotonKind::kDirect, PhotonKind::kIndirect}, &maps->global_attributes);
  }
  const uint64_t caustic_photons = counts[size_t(PhotonKind::kCaustic)];
  if (caustic) {
    maps->caustic = fill({PhotonKind::kCaustic}, &maps->caustic_attributes);
  } else if (caustic_photons > 0) {
    // Cannot happen in kAuto (no singular surface → no caustic photon); with kOff the caustic
    // photons are dropped on purpose and their light is missing from the image.
    spdlog::warn("photon maps: caustic map disabled: {} caustic photons dropped", caustic_photons);
  }
  maps->stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  maps->stats.stored_global = maps->global->size();
  maps->stats.stored_caustic = maps->caustic ? maps->caustic->size() : 0;
  maps->stats.stored_direct = maps->direct ? counts[size_t(PhotonKind::kDirect)] : 0;
}

}  // namespace pf
