#pragma once
// Job specs shared by the coordinator and end-to-end tests and the coordinator benchmarks, built the
// way a client sends them.

#include <cstdint>
#include <string>

#include "photonfarm/v1/farm.pb.h"

namespace pf::test_util {

// A valid photon-map job of the shipped Cornell box (the manifest's camera; 1000 photons, k = 20)
// at width x height, planned as skipping with stride 2, `rounds` rounds and 1 sample per pixel.
inline photonfarm::v1::JobSpec CornellPhotonMapSpec(const std::string& scene_hash, uint32_t width,
                                                    uint32_t height, uint32_t rounds, uint64_t seed) {
  photonfarm::v1::JobSpec spec;
  spec.set_scene_hash(scene_hash);
  photonfarm::v1::Camera& camera = *spec.mutable_camera();
  camera.mutable_eye()->set_y(1);
  camera.mutable_eye()->set_z(3.9);
  camera.mutable_look_at()->set_y(1);
  camera.mutable_up()->set_y(1);
  camera.set_vfov_degrees(39.3);
  camera.set_width(width);
  camera.set_height(height);
  photonfarm::v1::RenderSettings& settings = *spec.mutable_settings();
  settings.set_integrator(photonfarm::v1::INTEGRATOR_PHOTONMAP);
  settings.mutable_photon_map()->set_photons(1000);
  settings.mutable_photon_map()->set_k(20);
  photonfarm::v1::Skipping& skipping = *spec.mutable_plan()->mutable_skipping();
  skipping.set_stride(2);
  skipping.set_rounds(rounds);
  skipping.set_samples_per_pixel(1);
  spec.set_seed(seed);
  return spec;
}

// The largest job a coordinator admits: 65536 maps of 16 one-pixel tiles, 2^20 tasks
// (limits::kMaxTasksPerJob), path traced at 16 x 1.
inline photonfarm::v1::JobSpec LargestJobSpec(const std::string& scene_hash, uint64_t seed) {
  photonfarm::v1::JobSpec spec;
  spec.set_scene_hash(scene_hash);
  spec.mutable_camera()->set_width(16);
  spec.mutable_camera()->set_height(1);
  spec.mutable_settings()->set_integrator(photonfarm::v1::INTEGRATOR_PATH);
  spec.mutable_plan()->mutable_multiple_maps()->set_maps(65536);
  spec.mutable_plan()->mutable_multiple_maps()->set_samples_per_pixel(1);
  spec.mutable_plan()->mutable_multiple_maps()->set_tile_size(1);
  spec.set_seed(seed);
  return spec;
}

}  // namespace pf::test_util
