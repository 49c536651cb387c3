#pragma once
// Rendering a scene file in a unit test with one integrator (tests/common/*texture*_test.cpp):
// the maps built as a job would build them, the manifest's first camera, fixed seeds.

#include <filesystem>
#include <string>

#include "common/camera/camera.h"
#include "common/image/image.h"
#include "common/photon/photon_maps.h"
#include "common/render/integrator_factory.h"
#include "common/render/job_render_settings.h"
#include "common/render/render_settings_table.h"
#include "common/render/renderer.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"

namespace pf::render_test {

// width/height 0: the camera's own; `seed` the pixel samples'.
inline Image RenderScene(const SceneRuntime& scene, const std::string& integrator, uint32_t spp,
                         uint64_t photons, int width = 0, int height = 0, uint64_t seed = 3) {
  JobRenderSettings settings;
  SetRenderSetting(settings, "integrator", integrator, "integrator");
  settings.photons = photons;
  settings = settings.Resolved(scene.description);
  PhotonMaps maps;
  const IntegratorInputs inputs{.scene = &scene.accel, .lights = &scene.lights, .maps = &maps};
  if (Integrators().Find(integrator, "integrator").UsesPhotonMaps())
    maps = PhotonMaps::Build(scene.accel, scene.lights, settings.MapsOptions());
  const auto tracer = MakeIntegrator(integrator, settings, inputs);
  CameraSpec camera = scene.description.cameras.front();
  if (width > 0) camera.width = width;
  if (height > 0) camera.height = height;
  return RenderImage(*tracer, Camera(camera, scene.description.origin),
                     RenderOptions{.spp = spp, .seed = seed});
}

inline Image RenderScene(const std::filesystem::path& file, const std::string& integrator, uint32_t spp,
                         uint64_t photons) {
  const SceneRuntime scene(LoadScene(file));
  return RenderScene(scene, integrator, spp, photons);
}

}  // namespace pf::render_test
