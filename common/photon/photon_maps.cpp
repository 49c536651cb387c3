#include "common/photon/photon_maps.h"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <chrono>

namespace pf {
namespace {

std::unique_ptr<PhotonMap> MakeFilled(const PhotonMapsOptions& o,
                                      std::initializer_list<const TracedPhotons*> lists,
                                      PhotonAttributes* attributes) {
  auto map = MakePhotonMap(o.kind, o.structure);
  map->set_build_threads(o.tracing.threads);
  size_t n = 0;
  for (const auto* l : lists) n += l->size();
  // Compressing to 18 bytes (two arc functions and a frexp per photon) is independent per
  // photon: done in parallel into place, then added in one piece (same order as one by one).
  std::vector<Photon> compact(n);
  tbb::task_arena arena(o.tracing.threads > 0 ? o.tracing.threads : tbb::task_arena::automatic);
  size_t offset = 0;
  for (const auto* l : lists) {
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, l->size(), 16384), [&](const auto& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
          const TracedPhoton& p = (*l)[i];
          compact[offset + i] = Photon::Make(p.position, p.direction, p.power);
        }
      });
    });
    offset += l->size();
  }
  map->AddPhotons(compact);
  std::vector<Photon>().swap(compact);
  if (!o.keep_light_ids && !o.keep_origins) {
    map->PrepareForQuery();
    return map;
  }
  std::vector<const TracedPhoton*> traced;
  traced.reserve(n);
  for (const auto* l : lists)
    for (const TracedPhoton& p : *l) traced.push_back(&p);
  std::vector<uint32_t> original;
  map->PrepareForQuery(&original);
  if (o.keep_light_ids) attributes->light.resize(n);
  if (o.keep_origins) attributes->origin.resize(n);
  for (size_t i = 0; i < n; ++i) {
    if (o.keep_light_ids) attributes->light[i] = traced[original[i]]->light;
    if (o.keep_origins) attributes->origin[i] = traced[original[i]]->origin;
  }
  return map;
}

}  // namespace

PhotonMaps PhotonMaps::Build(const EmbreeScene& scene, const LightSampler& lights,
                             const PhotonMapsOptions& options) {
  PhotonMaps maps;
  maps.seed = options.tracing.map_seed;
  const bool need_caustic =
      options.caustic == CausticMapMode::kOn ||
      (options.caustic == CausticMapMode::kAuto && SceneNeedsCausticMap(scene.description()));
  if (options.caustic == CausticMapMode::kAuto && !need_caustic)
    spdlog::info("photon maps: no specular or glossy surface in the scene: no caustic map");

  const PhotonTracingResult traced = TracePhotons(scene, lights, options.tracing);
  maps.stats.emitted = traced.emitted;
  maps.stats.rays = traced.rays;
  maps.stats.trace_seconds = traced.seconds;
  maps.stats.emitted_power = traced.emitted_power;
  maps.stats.stored_power = traced.StoredPower();

  const auto t0 = std::chrono::steady_clock::now();
  if (options.separate_direct) {
    // Two independent maps: built concurrently, so that the serial top split of one kd-tree
    // overlaps with the other's build (each map is the same as when built alone).
    tbb::task_arena arena(options.tracing.threads > 0 ? options.tracing.threads : tbb::task_arena::automatic);
    arena.execute([&] {
      tbb::parallel_invoke(
          [&] { maps.global = MakeFilled(options, {&traced.indirect}, &maps.global_attributes); },
          [&] { maps.direct = MakeFilled(options, {&traced.direct}, &maps.direct_attributes); });
    });
  } else {
    maps.global = MakeFilled(options, {&traced.direct, &traced.indirect}, &maps.global_attributes);
  }
  if (need_caustic) {
    maps.caustic = MakeFilled(options, {&traced.caustic}, &maps.caustic_attributes);
  } else if (!traced.caustic.empty()) {
    // Cannot happen in kAuto (no singular surface → no caustic photon); with kOff the caustic
    // photons are dropped on purpose and their light is missing from the image.
    spdlog::warn("photon maps: caustic map disabled: {} caustic photons dropped", traced.caustic.size());
  }
  maps.stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  maps.stats.stored_global = maps.global->size();
  maps.stats.stored_caustic = maps.caustic ? maps.caustic->size() : 0;
  maps.stats.stored_direct = traced.direct.size();
  spdlog::info(
      "photon maps (seed {}): {} emitted, {} global + {} caustic stored ({} direct), trace {:.2f}s, build "
      "{:.2f}s",
      options.tracing.map_seed, traced.emitted, maps.stats.stored_global, maps.stats.stored_caustic,
      maps.stats.stored_direct, traced.seconds, maps.stats.build_seconds);
  return maps;
}

}  // namespace pf
