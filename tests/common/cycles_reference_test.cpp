// pf against an independent renderer: scenes/blender-box was built in Blender and exported by its
// glTF exporter (tools/blender/blender_box.py); cycles-lambert-64.exr is Cycles' render of it with
// Lambertian materials at 65536 samples per pixel, the scattering model blender-box-lambert.json
// gives pf. The two renderers then share the scene file, the camera and the BSDFs and differ only in
// light transport, so pf must agree with Cycles to within Monte Carlo noise: a wrong emitter unit,
// a one- or two-sided emission mix-up, a lost bounce or a camera mapped differently from Blender's
// all fail here (docs/results/blender-cycles.md has the measurements behind the tolerances).
// scenes/blender-studio adds what the box lacks — an image texture, a rough metal, smooth and rough
// glass, an HDR sky (the manifest's environment) and a spot lamp — with Cycles rendering the BSDFs
// pf reads from the exported file (tools/blender/blender_studio.py).
#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>
#include <vector>

#include "common/camera/camera.h"
#include "common/image/exr_io.h"
#include "common/image/image_diff.h"
#include "common/photon/photon_maps.h"
#include "common/render/emitter_coverage.h"
#include "common/render/integrator_factory.h"
#include "common/render/job_render_settings.h"
#include "common/render/render_settings_table.h"
#include "common/render/renderer.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"
#include "tests/common/scene_render_util.h"

namespace pf {
namespace {

const std::filesystem::path kSceneDir = std::filesystem::path(PF_SOURCE_DIR) / "scenes/blender-box";

struct Rendered {
  Image image;
  ImageDiffStats stats;
};

// `integrator` with the scene's resolved settings (photons: `photons`) at the reference's size.
Rendered RenderAgainstCycles(const char* integrator, uint32_t spp, uint64_t photons) {
  const Image reference = ReadExr(kSceneDir / "cycles-lambert-64.exr");
  const SceneRuntime scene(LoadScene(kSceneDir / "blender-box-lambert.json"));
  Rendered out;
  out.image =
      render_test::RenderScene(scene, integrator, spp, photons, reference.width(), reference.height(), 7);
  // No exclusion: rmse_lowfreq over every 4x4 block, the emitter's included.
  const std::vector<uint8_t> nothing_excluded(reference.width() * reference.height(), 0);
  out.stats = CompareImages(out.image, reference, &nothing_excluded);
  std::cout << integrator << " vs Cycles: mean ratio " << out.stats.mean_a / out.stats.mean_b
            << ", rmse_lowfreq " << out.stats.rmse_lowfreq / out.stats.display_white
            << " of display white, rmse_display " << out.stats.rmse_display << "\n";
  return out;
}

// The path tracer is unbiased like Cycles: at 512 spp the image mean must agree to 0.3 % and the
// 4x4-block means to 1 % of display white. Measured: mean ratio 1.0003, rmse_lowfreq 0.0014 of
// white, rmse_display 0.0046 (the noise of 512 spp against the reference's 65536). The white
// material at 0.81 instead of 0.8 already fails (mean ratio 1.0073).
TEST(CyclesReference, PathTracerAgreesWithCyclesOnTheBlenderBox) {
  const Rendered r = RenderAgainstCycles("path", 512, 0);
  ASSERT_EQ(r.stats.nonfinite_a, 0u);
  EXPECT_NEAR(r.stats.mean_a / r.stats.mean_b, 1.0, 0.003);
  EXPECT_LT(r.stats.rmse_lowfreq, 0.01 * r.stats.display_white);
  EXPECT_LT(r.stats.rmse_display, 0.02);
}

// The photon map (Wald 1999) is consistent, not unbiased: with its defaults and 200k photons its
// blur and boundary bias must stay below 2 % of the image mean and its block errors below 3 % of
// display white on this box. Measured: mean ratio 0.9985, rmse_lowfreq 0.0076 of white.
TEST(CyclesReference, PhotonMapStaysNearCyclesOnTheBlenderBox) {
  const Rendered r = RenderAgainstCycles("photonmap", 64, 200000);
  ASSERT_EQ(r.stats.nonfinite_a, 0u);
  EXPECT_NEAR(r.stats.mean_a / r.stats.mean_b, 1.0, 0.02);
  EXPECT_LT(r.stats.rmse_lowfreq, 0.03 * r.stats.display_white);
}

const std::filesystem::path kStudioDir = std::filesystem::path(PF_SOURCE_DIR) / "scenes/blender-studio";

// `integrator` on blender-studio at the 64 x 48 reference's size, judged away from the emitting
// panel (and its 2-pixel band) as `pf diff --scene` judges it.
ImageDiffStats StudioAgainstCycles(const char* integrator, uint32_t spp, uint64_t photons) {
  const Image reference = ReadExr(kStudioDir / "cycles-64x48.exr");
  const SceneRuntime scene(LoadScene(kStudioDir / "blender-studio.json"));
  const Image image =
      render_test::RenderScene(scene, integrator, spp, photons, reference.width(), reference.height(), 7);
  CameraSpec spec = scene.description.cameras.front();
  spec.width = reference.width();
  spec.height = reference.height();
  const std::vector<uint8_t> excluded = EmitterExclusionMask(
      EmitterCoverage(scene.accel, Camera(spec, scene.description.origin)), spec.width, spec.height);
  const ImageDiffStats stats = CompareImages(image, reference, &excluded);
  std::cout << integrator << " vs Cycles on blender-studio: mean ratio away from the emitter "
            << stats.mean_masked_a / stats.mean_masked_b << " (" << stats.pixels_masked
            << " pixels), rmse_lowfreq " << stats.rmse_lowfreq / stats.display_white << " of display white\n";
  return stats;
}

// The path tracer against Cycles where light arrives from an HDR sky, a spot lamp and an emitting
// panel, over a textured floor, copper and two kinds of glass. Measured at 256 spp: mean ratio
// 1.008 away from the panel, rmse_lowfreq 0.006 of white; pf's 65536-spp reference: 1.0076. Tolerance 1.5 %
// on the mean: the two renderers' models differ in small known ways (docs/results/blender-cycles.md:
// Cycles 3.4's spot lamp is dimmer off its axis by cos θ, its rough glass scatters between microfacets, its
// metal's Fresnel curve is not Schlick's), each below 1 % of this image's mean.
TEST(CyclesReference, PathTracerAgreesWithCyclesOnTheBlenderStudio) {
  const ImageDiffStats s = StudioAgainstCycles("path", 256, 0);
  ASSERT_EQ(s.nonfinite_a, 0u);
  ASSERT_GT(s.pixels_masked, 2500u);
  EXPECT_NEAR(s.mean_masked_a / s.mean_masked_b, 1.0, 0.015);
  EXPECT_LT(s.rmse_lowfreq, 0.02 * s.display_white);
}

// The photon map with the manifest's 2M photons (most sky photons leave this open scene: 3 % end
// in the global map): mean within 3 % of Cycles away from the panel. Measured: ratio 0.995, rmse_lowfreq
// 0.008 of white; with pf's default 200k photons 0.96, with 4M 1.001 (the bias falls with the photon count).
TEST(CyclesReference, PhotonMapStaysNearCyclesOnTheBlenderStudio) {
  const ImageDiffStats s = StudioAgainstCycles("photonmap", 64, 2000000);
  ASSERT_EQ(s.nonfinite_a, 0u);
  EXPECT_NEAR(s.mean_masked_a / s.mean_masked_b, 1.0, 0.03);
  EXPECT_LT(s.rmse_lowfreq, 0.03 * s.display_white);
}

}  // namespace
}  // namespace pf
