#pragma once
// The photon maps of one map seed (Wald 1999, §2.2): photon tracing plus the structures built
// over its output. "Model only what the scene needs": the caustic map is built only when the
// scene has singular surfaces (or when forced), and each decision is logged.
//
// One build path for local and distributed maps: PhotonMaps::Build traces the map as pieces
// [0, N) (TracePhotonChunk, photon_chunk.h) and fills and builds the maps from them with
// AssemblePhotonMaps, the function the coordinator calls on the pieces its workers traced
// (docs/farm.md, "Photon maps traced once"). What only a local build does comes before the
// pieces: resolving `caustic auto`, the pilot of `importance auto` and the importance map (§4.7),
// which every piece then reads. A local build is one piece [0, N): its stats.stored_power (kept
// in the map file) is then the whole trace's double sum bit for bit, which several pieces would
// only match up to float rounding (AssemblePhotonMaps); the photons, and so the maps and images,
// are the same for any cuts. One piece traced in parallel costs the CPU time of the former
// whole trace, and frees each traced list as soon as it is compressed to 18 bytes
// (docs/results/one-build-path.md).

#include <memory>
#include <mutex>
#include <string>

#include "common/camera/camera.h"
#include "common/photon/importance_map.h"
#include "common/photon/photon_map.h"
#include "common/photon/photon_tracer.h"

namespace pf {

enum class CausticMapMode { kAuto, kOn, kOff };

struct PhotonMapsOptions {
  PhotonTracerOptions tracing;
  PhotonMapKind kind = PhotonMapKind::kKdTree;
  PhotonMapOptions structure;
  CausticMapMode caustic = CausticMapMode::kAuto;
  // Keep the first-hit direct photons out of the global map (for estimators that compute
  // direct light separately, §4.2). Standalone rendering keeps them in.
  bool separate_direct = false;
  // With separate_direct: store those direct photons in a map of their own. Only PhotonDirect
  // (§4.2.3) and the local pass's gather hits (§4.3) read it; with Monte Carlo direct light and
  // no local pass nothing does, and the direct photons (more than half of all stored photons in
  // a closed room) are dropped: no balance, no bytes on the wire, no memory (model only what the
  // job needs). The global and caustic maps are the same either way.
  bool direct_map = true;
  // Per-photon attributes beyond the 18 bytes, kept only when an estimator needs them:
  // the emitting light (PhotonDirect, §4.2.3) and the previous path vertex (occlusion
  // testing, §4.1.1). 4 and 12 bytes per photon.
  bool keep_light_ids = false;
  bool keep_origins = false;
  // Importance-driven storing (Wald 1999, §4.7; importance_map.h): needs the camera.
  ImportanceOptions importance;
};

// Attributes of the photons of one map, indexed like PhotonMap::photon(i) (post-build order).
struct PhotonAttributes {
  std::vector<uint32_t> light;  // empty unless keep_light_ids
  std::vector<Vec3> origin;     // empty unless keep_origins
};

struct PhotonMapsStats {
  uint64_t emitted = 0;
  uint64_t stored_global = 0, stored_caustic = 0, stored_direct = 0;
  double trace_seconds = 0, build_seconds = 0;
  uint64_t rays = 0;
  Rgb emitted_power, stored_power;  // stored_power: Σ Φ over all stored photons (before compression)
  // Metropolis caustic splitting (§4.6.2): singular chains split, mutations tried and accepted.
  uint64_t chains = 0, mutations = 0, accepted = 0;
  // Importance (§4.7): whether the map was thinned, the diffuse hits it did not store, and the
  // importance map's size and build time (included in trace_seconds).
  bool importance = false;
  uint64_t rejected = 0;
  uint64_t importons = 0;
  double importance_seconds = 0;
};

// What `importance auto` measured and decided (§4.7): a pilot of kPilotPhotons photons traced
// against a pilot importance map, both from fixed seeds (so every map of a job decides alike).
struct ImportancePilot {
  uint64_t photons = 0, stored = 0, rejected = 0;  // diffuse hits = stored + rejected
  double rejected_fraction = 0;                    // ≈ 1 − mean acceptance probability
  double seconds = 0;
  bool enable = false;
};
inline constexpr uint64_t kImportancePilotPhotons = 16384;
inline constexpr uint64_t kImportancePilotImportons = 16384;
// `auto` enables importance when the pilot would drop more than this share of the diffuse hits
// (most photons land where the camera does not look; at 0.5 it also took office3 and scene8,
// whose cameras see most of their rooms: docs/results/importance.md).
inline constexpr double kImportanceAutoThreshold = 0.8;
ImportancePilot RunImportancePilot(const EmbreeScene& scene, const LightSampler& lights, const Camera& camera,
                                   const PhotonMapsOptions& options);

struct PhotonMaps {
  std::unique_ptr<PhotonMap> global;   // diffuse (+ direct unless separate_direct) photons
  std::unique_ptr<PhotonMap> caustic;  // null when not needed
  std::unique_ptr<PhotonMap> direct;   // only with separate_direct
  PhotonAttributes global_attributes, caustic_attributes, direct_attributes;
  PhotonMapsStats stats;
  uint64_t seed = 0;  // the map seed the photons were traced with

  // A structure an estimator derives from these maps and keeps with them, so that maps
  // shared through a cache pay for it once (the precomputed irradiance of the local pass,
  // estimators/precomputed_irradiance.h). `key` names what was built and with which options.
  struct Derived {
    std::mutex mutex;
    std::string key;
    std::shared_ptr<const void> value;
  };
  std::shared_ptr<Derived> derived = std::make_shared<Derived>();

  // `camera` (in the scene's frame) is required when options.importance.mode is not off.
  // stats.trace_seconds covers the importance map, the trace and the compression to 18 bytes;
  // build_seconds the maps' build (AssemblePhotonMaps).
  static PhotonMaps Build(const EmbreeScene& scene, const LightSampler& lights,
                          const PhotonMapsOptions& options, const Camera* camera = nullptr);
};

}  // namespace pf
