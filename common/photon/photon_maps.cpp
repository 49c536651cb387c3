#include "common/photon/photon_maps.h"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <optional>

#include "common/core/error.h"

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

// Seeds of the pilot of `importance auto`: fixed, not the map's, so the decision is a function of
// the scene, the camera and the settings alone.
constexpr uint64_t kPilotSeed = 0x70696c6f74ull;  // "pilot"

}  // namespace

ImportancePilot RunImportancePilot(const EmbreeScene& scene, const LightSampler& lights, const Camera& camera,
                                   const PhotonMapsOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  ImportanceOptions io = options.importance;
  io.importons = std::min<uint64_t>(
      io.importons > 0 ? io.importons : uint64_t(camera.width()) * uint64_t(camera.height()),
      kImportancePilotImportons);
  const ImportanceMap importance =
      ImportanceMap::Build(scene, camera, io, kPilotSeed, options.tracing.sampler, options.tracing.threads);
  PhotonTracerOptions to = options.tracing;
  to.photons = kImportancePilotPhotons;
  to.map_seed = kPilotSeed;
  to.importance = &importance;
  const PhotonTracingResult traced = TracePhotons(scene, lights, to);
  ImportancePilot pilot;
  pilot.photons = to.photons;
  pilot.stored = traced.direct.size() + traced.indirect.size() + traced.caustic.size();
  pilot.rejected = traced.rejected;
  const uint64_t hits = pilot.stored + pilot.rejected;
  pilot.rejected_fraction = hits > 0 ? double(pilot.rejected) / double(hits) : 0.0;
  pilot.enable = pilot.rejected_fraction > kImportanceAutoThreshold;
  pilot.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return pilot;
}

PhotonMaps PhotonMaps::Build(const EmbreeScene& scene, const LightSampler& lights,
                             const PhotonMapsOptions& options, const Camera* camera) {
  PhotonMaps maps;
  maps.seed = options.tracing.map_seed;
  // Wald 1999, §4.7: importance-driven storing.
  bool use_importance = options.importance.mode == ImportanceMode::kOn;
  if (options.importance.mode != ImportanceMode::kOff && !camera)
    throw InputError("importance-driven photon maps need the camera the image is rendered with");
  if (options.importance.mode == ImportanceMode::kAuto) {
    const ImportancePilot pilot = RunImportancePilot(scene, lights, *camera, options);
    use_importance = pilot.enable;
    spdlog::info(
        "auto importance = {}: pilot of {} photons: {} diffuse hits, {:.1f}% of them where the importance is "
        "low enough to drop them (threshold {:.0f}%; mean acceptance {:.3f}, p_min {}, strength {}), {:.2f}s",
        use_importance ? "on" : "off", pilot.photons, pilot.stored + pilot.rejected,
        100.0 * pilot.rejected_fraction, 100.0 * kImportanceAutoThreshold, 1.0 - pilot.rejected_fraction,
        options.importance.min_probability, options.importance.strength, pilot.seconds);
  }
  std::optional<ImportanceMap> importance;
  PhotonTracerOptions tracing = options.tracing;
  if (use_importance) {
    importance = ImportanceMap::Build(scene, *camera, options.importance, options.tracing.map_seed,
                                      options.tracing.sampler, options.tracing.threads);
    tracing.importance = &*importance;
    maps.stats.importance = true;
    maps.stats.importons = importance->stats().stored;
    maps.stats.importance_seconds = importance->stats().seconds;
  }
  const bool need_caustic =
      options.caustic == CausticMapMode::kOn ||
      (options.caustic == CausticMapMode::kAuto && SceneNeedsCausticMap(scene.description()));
  if (options.caustic == CausticMapMode::kAuto && !need_caustic)
    spdlog::info("photon maps: no specular or glossy surface in the scene: no caustic map");

  const PhotonTracingResult traced = TracePhotons(scene, lights, tracing);
  maps.stats.emitted = traced.emitted;
  maps.stats.rays = traced.rays;
  maps.stats.rejected = traced.rejected;
  maps.stats.trace_seconds = traced.seconds + maps.stats.importance_seconds;
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
          [&] {
            if (options.direct_map)
              maps.direct = MakeFilled(options, {&traced.direct}, &maps.direct_attributes);
          });
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
  maps.stats.stored_direct = maps.direct ? traced.direct.size() : 0;
  spdlog::info(
      "photon maps (seed {}): {} emitted, {} global + {} caustic stored ({} direct), trace {:.2f}s, build "
      "{:.2f}s",
      options.tracing.map_seed, traced.emitted, maps.stats.stored_global, maps.stats.stored_caustic,
      maps.stats.stored_direct, traced.seconds, maps.stats.build_seconds);
  if (options.tracing.caustic_split > 1)
    spdlog::info(
        "caustic splitting (seed {}): S = {} by {}: {} caustic photons; {} chains split, {} of {} mutations "
        "accepted",
        options.tracing.map_seed, options.tracing.caustic_split,
        CausticSplitMethodName(options.tracing.caustic_split_method), traced.caustic.size(), traced.chains,
        traced.accepted, traced.mutations);
  if (importance)
    spdlog::info(
        "importance (seed {}): {} importons stored of {} traced ({:.2f}s); {} diffuse hits not stored "
        "({:.1f}%), "
        "p_min {}, strength {}",
        options.tracing.map_seed, importance->stats().stored, importance->stats().traced,
        importance->stats().seconds, traced.rejected,
        100.0 * double(traced.rejected) /
            double(std::max<uint64_t>(
                1, traced.rejected + traced.direct.size() + traced.indirect.size() + traced.caustic.size())),
        options.importance.min_probability, options.importance.strength);
  return maps;
}

}  // namespace pf
