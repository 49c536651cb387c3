// Renders with the GGX lobes (common/materials/bsdf_microfacet.h) through the unchanged
// integrators: a furnace whose walls only emit (Le = 1, ρ = 0), so that a convex object's pixel
// reads its directional albedo ∫ f·|cos| dωi exactly, compared with the BSDF's own Monte Carlo
// albedo; and the shipped cornell-sphere-rough manifest (a rough metal and a rough glass sphere)
// with both integrators, finite and not black.

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/lights/light_sampler.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_maps.h"
#include "common/render/job_render_settings.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"
#include "tests/common/bsdf_test_support.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

// A quad of `material` facing the camera in a furnace of pure emitters; the 10° camera sees only
// the quad, within 5° of normal incidence.
testing::SceneWithCamera QuadInEmitterFurnace(const Material& material) {
  testing::SceneWithCamera f;
  f.scene = testing::FurnaceScene(0.0f);
  const uint32_t id = testing::AddMaterial(f.scene, material);
  testing::AddQuad(f.scene, {-0.3f, -0.3f, -0.5f}, {0.3f, -0.3f, -0.5f}, {0.3f, 0.3f, -0.5f},
                   {-0.3f, 0.3f, -0.5f}, id);
  f.camera =
      testing::LookAtCamera(Vec3(0.0f, 0.0f, 0.5f), Vec3(0.0f, 0.0f, -0.5f), Vec3(0, 1, 0), 10.0f, 4, 4);
  return f;
}

double RenderMean(const testing::SceneWithCamera& f, uint32_t spp) {
  const EmbreeScene accel(f.scene);
  const LightSampler lights(accel);
  const PathTracer tracer(accel, lights, PathTracerOptions{.rr_start_depth = 40});
  RenderStats stats;
  const Image img = RenderImage(tracer, Camera(f.camera), RenderOptions{.spp = spp, .seed = 7}, &stats);
  EXPECT_EQ(stats.nonfinite_samples, 0u);
  double sum = 0;
  for (const Rgb& c : img.pixels()) sum += c.Mean();
  return sum / double(img.size());
}

// The path tracer (NEE + BSDF sampling, MIS) reads the quad's albedo at normal incidence: the
// BSDF's Sample weights averaged (1 % tolerance: the pixels' view angles span 0-5°, the albedo's
// change over that is < 0.2 %; the render's noise at 4096 spp is < 0.3 %).
TEST(MicrofacetFurnaceRender, PathTracerReadsTheAlbedo) {
  const struct {
    const char* name;
    Material m;
  } cases[] = {
      {"metal r=0.3", Material{.specular_reflectance = Rgb(1.0f),
                               .microfacet = Material::Microfacet::kConductor,
                               .microfacet_roughness = 0.3f}},
      {"metal r=1", Material{.specular_reflectance = Rgb(1.0f),
                             .microfacet = Material::Microfacet::kConductor,
                             .microfacet_roughness = 1.0f}},
      {"rough glass r=0.5", Material{.specular_transmittance = Rgb(1.0f),
                                     .ior = 1.5f,
                                     .microfacet = Material::Microfacet::kDielectric,
                                     .microfacet_roughness = 0.5f}},
  };
  for (const auto& c : cases) {
    const Bsdf bsdf(c.m, Vec3(0, 0, 1), Vec3(0, 0, 1));
    const bsdf_test::Albedo a = bsdf_test::EstimateAlbedo(bsdf, Vec3(0, 0, 1), 1'000'000, 5);
    const double rendered = RenderMean(QuadInEmitterFurnace(c.m), 4096);
    std::printf("[furnace render] %s: rendered %.4f, albedo %.4f\n", c.name, rendered, a.mean[0]);
    EXPECT_NEAR(rendered, a.mean[0], 0.01 * a.mean[0]) << c.name;
    EXPECT_LE(rendered, 1.0 + 0.005) << c.name;
  }
}

// The cornell-sphere-rough manifest variant renders finite, not black, with both integrators.
TEST(MicrofacetScene, CornellSphereRoughRendersWithBothIntegrators) {
  const SceneDescription scene =
      LoadScene(std::filesystem::path(PF_SOURCE_DIR) / "scenes/cornell-sphere/cornell-sphere-rough.json");
  int microfacet = 0;
  for (const Material& m : scene.materials) microfacet += m.microfacet != Material::Microfacet::kNone;
  EXPECT_EQ(microfacet, 2);
  CameraSpec cam = scene.cameras.front();
  cam.width = cam.height = 24;
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  auto check = [](const Image& img, const RenderStats& stats, const char* what) {
    double sum = 0;
    for (const Rgb& c : img.pixels()) {
      ASSERT_TRUE(c.IsFinite()) << what;
      sum += c.Mean();
    }
    EXPECT_GT(sum, 0.0) << what;
    EXPECT_EQ(stats.nonfinite_samples, 0u) << what;
  };
  RenderStats path_stats;
  const PathTracer tracer(accel, lights);
  check(RenderImage(tracer, Camera(cam), RenderOptions{.spp = 8, .seed = 3}, &path_stats), path_stats,
        "path");

  // The photon map with the manifest's suggested settings but fewer photons (the job's defaults).
  JobRenderSettings job;
  job.photons = 30000;
  const JobRenderSettings resolved = job.Resolved(scene);
  PhotonMapsOptions maps_options = resolved.MapsOptions();
  maps_options.tracing.map_seed = 2;
  RenderStats pm_stats;
  const PhotonMaps maps = PhotonMaps::Build(accel, lights, maps_options);
  const PhotonMapIntegrator integrator(accel, &lights, maps, resolved.IntegratorOptions(accel.bounds()));
  check(RenderImage(integrator, Camera(cam), RenderOptions{.spp = 4, .seed = 1}, &pm_stats), pm_stats,
        "photon map");
}

}  // namespace
}  // namespace pf
