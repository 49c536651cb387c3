#pragma once
// The photon maps of one map seed (Wald 1999, §2.2): photon tracing plus the structures built
// over its output. "Model only what the scene needs": the caustic map is built only when the
// scene has singular surfaces (or when forced), and each decision is logged.

#include <memory>
#include <mutex>
#include <string>

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
  // Per-photon attributes beyond the 18 bytes, kept only when an estimator needs them:
  // the emitting light (PhotonDirect, §4.2.3) and the previous path vertex (occlusion
  // testing, §4.1.1). 4 and 12 bytes per photon.
  bool keep_light_ids = false;
  bool keep_origins = false;
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
};

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

  static PhotonMaps Build(const EmbreeScene& scene, const LightSampler& lights,
                          const PhotonMapsOptions& options);
};

}  // namespace pf
