#include "common/photon/photon_maps.h"

#include <spdlog/spdlog.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <optional>

#include "common/core/error.h"
#include "common/photon/photon_maps_fill.h"

namespace pf {
namespace {

// One map from the traced lists of `kinds`, concatenated in that order.
std::unique_ptr<PhotonMap> MakeFilled(const PhotonMapsOptions& o, const PhotonTracingResult& traced,
                                      std::initializer_list<PhotonKind> kinds, PhotonAttributes* attributes) {
  const std::array<const TracedPhotons*, 3> by_kind = {&traced.direct, &traced.indirect, &traced.caustic};
  size_t n = 0;
  for (PhotonKind k : kinds) n += by_kind[size_t(k)]->size();
  // Compressing to 18 bytes (two arc functions and a frexp per photon) is independent per
  // photon: done in parallel into place, then added in one piece (same order as one by one).
  std::vector<Photon> compact(n);
  tbb::task_arena arena(o.tracing.threads > 0 ? o.tracing.threads : tbb::task_arena::automatic);
  size_t offset = 0;
  for (PhotonKind k : kinds) {
    const TracedPhotons& l = *by_kind[size_t(k)];
    arena.execute([&] {
      tbb::parallel_for(tbb::blocked_range<size_t>(0, l.size(), 16384), [&](const auto& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
          const TracedPhoton& p = l[i];
          compact[offset + i] = Photon::Make(p.position, p.direction, p.power);
        }
      });
    });
    offset += l.size();
  }
  const auto in_order = [&] {
    PhotonAttributes a;
    for (PhotonKind k : kinds)
      for (const TracedPhoton& p : *by_kind[size_t(k)]) {
        if (o.keep_light_ids) a.light.push_back(p.light);
        if (o.keep_origins) a.origin.push_back(p.origin);
      }
    return a;
  };
  return BuildPhotonMap(o, std::move(compact), in_order, attributes);
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

  FillPhotonMaps(
      options, need_caustic, {traced.direct.size(), traced.indirect.size(), traced.caustic.size()},
      [&](std::initializer_list<PhotonKind> kinds, PhotonAttributes* attributes) {
        return MakeFilled(options, traced, kinds, attributes);
      },
      &maps);
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
