#include "common/photon/photon_maps.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <optional>
#include <vector>

#include "common/core/error.h"
#include "common/photon/photon_chunk.h"

namespace pf {
namespace {

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
  // The options the pieces are traced and assembled with: the importance map every piece reads,
  // and `caustic auto` resolved.
  PhotonMapsOptions resolved = options;
  std::optional<ImportanceMap> importance;
  if (use_importance) {
    importance = ImportanceMap::Build(scene, *camera, options.importance, options.tracing.map_seed,
                                      options.tracing.sampler, options.tracing.threads);
    resolved.tracing.importance = &*importance;
  }
  const bool need_caustic =
      options.caustic == CausticMapMode::kOn ||
      (options.caustic == CausticMapMode::kAuto && SceneNeedsCausticMap(scene.description()));
  if (options.caustic == CausticMapMode::kAuto && !need_caustic)
    spdlog::info("photon maps: no specular or glossy surface in the scene: no caustic map");
  resolved.caustic = need_caustic ? CausticMapMode::kOn : CausticMapMode::kOff;

  // The map as pieces [0, N), assembled as the coordinator assembles its workers' pieces: one
  // piece (photon_maps.h says why).
  std::vector<PhotonChunk> pieces;
  if (options.tracing.photons > 0)
    pieces.push_back(TracePhotonChunk(scene, lights, resolved, 0, options.tracing.photons));
  uint64_t traced_caustic = 0, traced_stored = 0;
  for (const PhotonChunk& c : pieces) {
    traced_caustic += c.lists[size_t(PhotonKind::kCaustic)].photons.size();
    traced_stored += c.counts.stored;
  }
  PhotonMaps maps = AssemblePhotonMaps(pieces, resolved);
  std::vector<PhotonChunk>().swap(pieces);
  PhotonMapsStats& st = maps.stats;
  const double trace_seconds = st.trace_seconds;
  if (importance) {
    st.importance = true;
    st.importons = importance->stats().stored;
    st.importance_seconds = importance->stats().seconds;
    st.trace_seconds += st.importance_seconds;
  }
  spdlog::info(
      "photon maps (seed {}): {} emitted, {} global + {} caustic stored ({} direct), trace {:.2f}s, build "
      "{:.2f}s",
      options.tracing.map_seed, st.emitted, st.stored_global, st.stored_caustic, st.stored_direct,
      trace_seconds, st.build_seconds);
  if (options.tracing.caustic_split > 1)
    spdlog::info(
        "caustic splitting (seed {}): S = {} by {}: {} caustic photons; {} chains split, {} of {} mutations "
        "accepted",
        options.tracing.map_seed, options.tracing.caustic_split,
        CausticSplitMethodName(options.tracing.caustic_split_method), traced_caustic, st.chains, st.accepted,
        st.mutations);
  if (importance)
    spdlog::info(
        "importance (seed {}): {} importons stored of {} traced ({:.2f}s); {} diffuse hits not stored "
        "({:.1f}%), p_min {}, strength {}",
        options.tracing.map_seed, importance->stats().stored, importance->stats().traced,
        importance->stats().seconds, st.rejected,
        100.0 * double(st.rejected) / double(std::max<uint64_t>(1, st.rejected + traced_stored)),
        options.importance.min_probability, options.importance.strength);
  return maps;
}

}  // namespace pf
