#pragma once
// Shared by the local-pass tests (direct_light_test, precomputed_irradiance_test,
// irradiance_cache_test, photon_map_integrator_test): photon maps built for an integrator's
// options, and the furnace check of the local pass (Wald 1999, §4.3).

#include <gtest/gtest.h>

#include "common/photon/photon_maps.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "tests/common/test_scenes.h"

namespace pf::testing {

// The photon maps `io` needs: `photons` emitted, seeded by `seed`, traced on `threads` threads
// (0 = all cores; the maps do not depend on it).
inline PhotonMaps MapsFor(const EmbreeScene& accel, const LightSampler& lights,
                          const PhotonMapIntegratorOptions& io, uint64_t photons, uint64_t seed,
                          int threads = 0) {
  PhotonMapsOptions mo;
  mo.tracing.photons = photons;
  mo.tracing.map_seed = seed;
  mo.tracing.threads = threads;
  ConfigureMapsFor(io, &mo);
  return PhotonMaps::Build(accel, lights, mo);
}

// For Monte Carlo direct light and PhotonDirect in turn, in a scene with direct light only (no
// global photon, asserted): the integrator over 20000 photons (seed 5) and its name, to `check`.
template <typename Check>
void ForEachSeparateDirectIntegrator(const EmbreeScene& accel, const LightSampler& lights, Check&& check) {
  for (const DirectLightMode mode : {DirectLightMode::kMonteCarlo, DirectLightMode::kPhotonDirect}) {
    PhotonMapIntegratorOptions io;
    io.direct = mode;
    const PhotonMaps maps = MapsFor(accel, lights, io, 20000, 5);
    EXPECT_EQ(maps.global->size(), 0u) << "only direct light: no indirect photon";
    const PhotonMapIntegrator integrator(accel, &lights, maps, io);
    check(integrator, mode == DirectLightMode::kMonteCarlo ? "photon map, Monte Carlo direct"
                                                           : "photon map, PhotonDirect");
  }
}

// The local pass of the furnace checks: final gathering with 16 rays from the k = 50 photon-map
// estimate, direct light by `mode` (direct photons estimated as the global ones).
inline PhotonMapIntegratorOptions FurnaceLocalPassOptions(DirectLightMode mode) {
  PhotonMapIntegratorOptions io;
  io.global.k = 50;
  io.local_pass_rays = 16;
  io.direct = mode;
  io.direct_photons = io.global;
  return io;
}

// Final gathering (16 rays, k = 50) from the photon-map estimate in the furnace of albedo 0.8
// must give Le / (1 - a) = 5 within 1 %, with and without Monte Carlo direct light, for the
// local pass's `lookup`.
inline void ExpectFurnaceLocalPassWithinOnePercent(LocalPassLookup lookup, int threads) {
  const SceneDescription s = FurnaceScene(0.8f);
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  for (DirectLightMode mode : {DirectLightMode::kNone, DirectLightMode::kMonteCarlo}) {
    PhotonMapIntegratorOptions io = FurnaceLocalPassOptions(mode);
    io.local_pass_lookup = lookup;
    const PhotonMaps maps = MapsFor(accel, lights, io, 200000, 4, threads);
    const PhotonMapIntegrator integrator(accel, &lights, maps, io);
    const Image img = RenderImage(integrator, Camera(FurnaceCamera()), RenderOptions{.spp = 64, .seed = 2});
    for (size_t i = 0; i < img.size(); ++i)
      ASSERT_NEAR(img[i].Mean(), 5.0f, 0.05f) << "pixel " << i << " direct mode " << int(mode);
  }
}

}  // namespace pf::testing
