// Punctual lights (common/scene/punctual_light.h, common/lights/light_sampler.h) against their
// analytic values: a Lambertian plane under a point light has E = I·cos θ/d², under a directional
// light E = E⊥·cos θ, under a spot the same times the glTF falloff; its radiance is ρ/π·E. Both
// integrators (path tracer; photon map with Monte Carlo and with PhotonDirect direct light), per
// pixel, against the analytic mean over the pixel. And the photons: their power is the lights'.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <stdexcept>
#include <string>

#include "common/estimators/direct_light.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon_tracer.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/scene/metallic_roughness.h"
#include "tests/common/furnace_local_pass.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;
using testing::AddSphere;

constexpr float kAlbedo = 0.5f;
// Per pixel: the rendered value within 1 % of the analytic pixel mean (plus 1e-4 of the image's
// peak, for pixels the light barely reaches). The path tracer's estimate of this scene has no
// noise but the pixel's jitter (one light, one bounce that escapes), so 64 samples suffice.
constexpr double kRelativeTolerance = 0.01;
constexpr uint32_t kSpp = 64;

// A 40 × 40 Lambertian floor at z = 0 (normal +z) and nothing else: only direct light.
SceneDescription FloorWith(const PunctualLight& light) {
  SceneDescription s;
  const uint32_t floor = AddMaterial(s, Material{.name = "floor", .diffuse_reflectance = Rgb(kAlbedo)});
  AddQuad(s, {-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}, floor);
  s.punctual_lights.push_back(light);
  s.punctual_lights.back().light = 0;
  s.num_lights = 1;
  return s;
}

CameraSpec FloorCamera() {
  return testing::LookAtCamera(Vec3(0, -0.5f, 4.0f), Vec3(0, 0, 0), Vec3(0, 1, 0), 50, 16, 12);
}

PunctualLight PointLight() {
  return PunctualLight{
      .kind = PunctualLight::Kind::kPoint, .position = {0.4, -0.2, 2.0}, .intensity = Rgb(3, 4, 5)};
}

PunctualLight SpotLight() {
  return PunctualLight{.kind = PunctualLight::Kind::kSpot,
                       .position = {0.3, 0.1, 2.0},
                       .direction = Normalize(Vec3(0.1f, 0.0f, -1.0f)),
                       .intensity = Rgb(6, 5, 4),
                       .inner_cone_deg = 20,
                       .outer_cone_deg = 35};
}

PunctualLight DirectionalLight() {
  return PunctualLight{.kind = PunctualLight::Kind::kDirectional,
                       .direction = Normalize(Vec3(0.3f, 0.2f, -1.0f)),
                       .intensity = Rgb(2, 1.5f, 1)};
}

// The irradiance the light sends to the floor point p (normal +z), in double, from the formulas.
Rgb AnalyticIrradiance(const PunctualLight& l, const Vec3& p) {
  if (l.kind == PunctualLight::Kind::kDirectional)
    return l.intensity * float(std::max(0.0, -double(l.direction.z)));
  const Vec3d d = l.position - Vec3d(p);
  const double d2 = LengthSquared(d), dist = std::sqrt(d2);
  const double cos_surface = d.z / dist;
  double falloff = 1.0;
  if (l.kind == PunctualLight::Kind::kSpot) {
    const double cos_axis = -Dot(d, Vec3d(l.direction)) / dist;
    const double ci = std::cos(l.inner_cone_deg * M_PI / 180), co = std::cos(l.outer_cone_deg * M_PI / 180);
    const double t = std::clamp((cos_axis - co) / (ci - co), 0.0, 1.0);
    falloff = t * t;
  }
  return l.intensity * float(std::max(0.0, cos_surface) * falloff / d2);
}

// ρ/π·E averaged over the pixel (a 16 × 16 grid of the camera's rays through it, to the floor).
Image AnalyticImage(const PunctualLight& l) {
  const Camera camera(FloorCamera());
  Image img(camera.width(), camera.height());
  constexpr int kGrid = 16;
  for (int y = 0; y < camera.height(); ++y)
    for (int x = 0; x < camera.width(); ++x) {
      Rgb sum(0.0f);
      for (int j = 0; j < kGrid; ++j)
        for (int i = 0; i < kGrid; ++i) {
          const Ray r = camera.GenerateRay(x, y, (i + 0.5f) / kGrid, (j + 0.5f) / kGrid);
          const Vec3 p = r.origin + r.direction * (-r.origin.z / r.direction.z);
          sum += AnalyticIrradiance(l, p) * (kAlbedo / kPi);
        }
      img.at(x, y) = sum * (1.0f / (kGrid * kGrid));
    }
  return img;
}

void ExpectMatches(const Image& got, const Image& want, const std::string& what) {
  double peak = 0;
  for (const Rgb& c : want.pixels()) peak = std::max(peak, double(c.Max()));
  ASSERT_GT(peak, 0.0) << what << ": the analytic image is black";
  double worst = 0;  // the largest relative error of a pixel at 1 % of the peak or more
  for (int y = 0; y < want.height(); ++y)
    for (int x = 0; x < want.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double w = want.at(x, y)[c];
        ASSERT_NEAR(got.at(x, y)[c], w, kRelativeTolerance * w + 1e-4 * peak)
            << what << " pixel (" << x << "," << y << ") channel " << c;
        if (w >= 0.01 * peak) worst = std::max(worst, std::fabs(got.at(x, y)[c] - w) / w);
      }
  std::printf("[ analytic ] %s: largest relative pixel error %.2e\n", what.c_str(), worst);
}

void ExpectBothIntegratorsMatch(const PunctualLight& light, const std::string& what) {
  const SceneDescription scene = FloorWith(light);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 1u);
  const Image want = AnalyticImage(light);
  ExpectMatches(
      RenderImage(PathTracer(accel, lights), Camera(FloorCamera()), RenderOptions{.spp = kSpp, .seed = 3}),
      want, what + ", path tracer");
  testing::ForEachSeparateDirectIntegrator(
      accel, lights, [&](const Integrator& integrator, const char* name) {
        ExpectMatches(RenderImage(integrator, Camera(FloorCamera()), RenderOptions{.spp = kSpp, .seed = 3}),
                      want, what + ", " + name);
      });
}

// A glossy floor (GGX metal, roughness 0.5: a lobe the photon-map integrator follows by tracing
// rays, which can never hit a delta light) under a point and a directional light: the photon-map
// integrators render what the path tracer renders (its next-event estimate sees both lights),
// not black. With `sky`, a dim uniform environment too, the last light of the scene: the
// punctual lights are then not the last lights (a loop over "the last punctual().size() lights"
// evaluated the environment as a delta light and crashed).
void ExpectGlossyFloorSeesPunctualLights(bool sky) {
  SceneDescription scene;
  const uint32_t metal = AddMaterial(scene, MetallicRoughnessMaterial(MetallicRoughness{
                                                .base_color = Rgb(0.9f, 0.7f, 0.5f), .roughness = 0.5f}));
  AddQuad(scene, {-20, -20, 0}, {20, -20, 0}, {20, 20, 0}, {-20, 20, 0}, metal);
  scene.punctual_lights = {PointLight(), DirectionalLight()};
  scene.punctual_lights[0].light = 0;
  scene.punctual_lights[1].light = 1;
  scene.num_lights = 2;
  if (sky) {
    scene.environment.emplace();
    scene.environment->color = Rgb(0.002f);
    scene.environment->light = scene.num_lights++;
  }
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  const Image want =
      RenderImage(PathTracer(accel, lights), Camera(FloorCamera()), RenderOptions{.spp = 4096, .seed = 3});
  double peak = 0;
  for (const Rgb& c : want.pixels()) peak = std::max(peak, double(c.Max()));
  ASSERT_GT(peak, 0.0) << "the path tracer renders the glossy floor black";
  testing::ForEachSeparateDirectIntegrator(
      accel, lights, [&](const Integrator& integrator, const char* name) {
        const Image got =
            RenderImage(integrator, Camera(FloorCamera()), RenderOptions{.spp = 4096, .seed = 3});
        double sum_got = 0, sum_want = 0;
        for (size_t i = 0; i < got.size(); ++i) {
          sum_got += got[i].Mean();
          sum_want += want[i].Mean();
          // Per pixel: the same camera jitter, one bounce, delta lights only: the same value up to
          // the pixel's sampling of a highlight: 4096 samples keep it within 2 % of the peak.
          EXPECT_NEAR(got[i].Mean(), want[i].Mean(), 0.02 * peak) << name << " pixel " << i;
        }
        EXPECT_NEAR(sum_got, sum_want, 0.005 * sum_want) << name;
      });
}

TEST(PunctualLights, GlossyFloorSeesPunctualLightsWithEveryIntegrator) {
  ExpectGlossyFloorSeesPunctualLights(false);
}

TEST(PunctualLights, GlossyFloorSeesPunctualLightsBesideAnEnvironment) {
  ExpectGlossyFloorSeesPunctualLights(true);
}

TEST(PunctualLights, FloorUnderAPointLightIsICosOverDistanceSquared) {
  ExpectBothIntegratorsMatch(PointLight(), "point");
}

TEST(PunctualLights, FloorUnderADirectionalLightIsECos) {
  ExpectBothIntegratorsMatch(DirectionalLight(), "directional");
}

TEST(PunctualLights, FloorUnderASpotLightHasTheConeFalloff) {
  ExpectBothIntegratorsMatch(SpotLight(), "spot");
}

// The falloff at the cone's edges, through LightSampler::Incidence: full intensity up to the inner
// angle, (1/2)² where cos θ is halfway between the cones' cosines, 0 from the outer angle on.
TEST(PunctualLights, SpotFalloffAtTheConeEdges) {
  PunctualLight spot = SpotLight();
  spot.position = {0, 0, 2};
  spot.direction = Vec3(0, 0, -1);
  const SceneDescription scene = FloorWith(spot);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  const LightSample ls = lights.SampleLight(0, 0.5f, 0.5f, 0.5f);
  ASSERT_TRUE(ls.delta());
  EXPECT_EQ(ls.pdf_area, 1.0f);
  const double ci = std::cos(20 * M_PI / 180), co = std::cos(35 * M_PI / 180);
  const auto at_angle = [&](double cos_theta) {
    const double tan_theta = std::sqrt(1 - cos_theta * cos_theta) / cos_theta;
    const Vec3 p(float(2 * tan_theta), 0, 0);
    const DeltaIncidence in = lights.Incidence(ls, p);
    const double d2 = 4 + double(p.x) * p.x;
    return double(in.irradiance.r) / (6.0 / d2);  // the falloff: E / (I/d²)
  };
  EXPECT_NEAR(at_angle(1.0), 1.0, 1e-6);
  EXPECT_NEAR(at_angle(ci + 1e-5), 1.0, 1e-3);
  EXPECT_NEAR(at_angle(0.5 * (ci + co)), 0.25, 1e-3);
  EXPECT_NEAR(at_angle(co + 1e-5), 0.0, 1e-3);
  EXPECT_EQ(at_angle(co - 1e-3), 0.0);
  EXPECT_EQ(at_angle(0.5), 0.0);
}

// Emitted power accounting (§2.2): inside a closed sphere every photon is stored at its first
// hit, so the direct photons of each light sum to its power 4π·I (point) and
// 2π·I·[(1 − cos θi) + (cos θi − cos θo)/3] (spot), and the spot's photons fill its inner cone
// with the share (1 − cos θi)/[(1 − cos θi) + (cos θi − cos θo)/3] and never leave the outer one.
TEST(PunctualLights, PhotonPowerIsTheLightsPower) {
  SceneDescription s;
  AddSphere(s, Vec3(0.0f), 3.0f, 5, AddMaterial(s, Material{.diffuse_reflectance = Rgb(0.5f)}), true,
            kNoLight, false);
  PunctualLight point = PointLight();
  point.position = {0.2, 0.1, -0.3};
  point.light = 0;
  PunctualLight spot = SpotLight();
  spot.position = {-0.2, 0.0, 0.5};
  spot.light = 1;
  s.punctual_lights = {point, spot};
  s.num_lights = 2;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 2u);
  ASSERT_EQ(lights.num_emitters(), 2u);
  const double ci = std::cos(20 * M_PI / 180), co = std::cos(35 * M_PI / 180);
  const double cone = (1 - ci) + (ci - co) / 3;
  const Rgb point_power = point.intensity * float(4 * M_PI);
  const Rgb spot_power = spot.intensity * float(2 * M_PI * cone);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(lights.total_power()[c], (point_power + spot_power)[c], 1e-4 * 100);

  PhotonTracerOptions o;
  o.photons = 40960;
  const PhotonTracingResult r = TracePhotons(accel, lights, o);
  EXPECT_EQ(r.emitted, o.photons);
  ASSERT_GT(r.direct.size(), 0u);
  Rgb per_light[2];
  double spot_count = 0, spot_inner = 0;
  for (const TracedPhoton& p : r.direct) {
    ASSERT_LT(p.light, 2u);
    per_light[p.light] += p.power;
    if (p.light == 1) {
      const Vec3 dir = Normalize(p.position - Vec3(spot.position));
      const double cos_axis = Dot(dir, spot.direction);
      EXPECT_GE(cos_axis, co - 1e-3) << "a spot photon outside the outer cone";
      spot_count += 1;
      spot_inner += cos_axis >= ci;
    }
  }
  EXPECT_EQ(r.direct.size(), size_t(o.photons)) << "every photon's first hit is on the sphere";
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(per_light[0][c], point_power[c], 1e-3 * point_power[c]) << "point, channel " << c;
    EXPECT_NEAR(per_light[1][c], spot_power[c], 1e-3 * spot_power[c]) << "spot, channel " << c;
  }
  EXPECT_NEAR(spot_inner / spot_count, (1 - ci) / cone, 5e-3);
  std::printf(
      "[ analytic ] photon power / light power: point %.6f, spot %.6f; spot inner-cone share %.4f for %.4f\n",
      per_light[0].g / point_power.g, per_light[1].g / spot_power.g, spot_inner / spot_count,
      (1 - ci) / cone);
}

// A hard-edged spot (inner = outer angle: Blender's export of a spot lamp without blend): full
// intensity up to the cone's angle and nothing beyond, no division by the empty falloff band, and
// photons of power 2π·I·(1 − cos θo) in all, every one inside the cone.
TEST(PunctualLights, AHardEdgedSpotLightsItsConeFullyAndNothingBeyond) {
  PunctualLight spot = SpotLight();
  spot.inner_cone_deg = spot.outer_cone_deg = 30;
  spot.position = {0, 0, 2};
  spot.direction = Vec3(0, 0, -1);
  const double co = std::cos(30 * M_PI / 180);
  {
    const SceneDescription scene = FloorWith(spot);
    const EmbreeScene accel(scene);
    const LightSampler lights(accel);
    const LightSample ls = lights.SampleLight(0, 0.5f, 0.5f, 0.5f);
    const auto falloff_at = [&](double cos_theta) {
      const double tan_theta = std::sqrt(1 - cos_theta * cos_theta) / cos_theta;
      const Vec3 p(float(2 * tan_theta), 0, 0);
      const double d2 = 4 + double(p.x) * p.x;
      return double(lights.Incidence(ls, p).irradiance.r) / (6.0 / d2);
    };
    EXPECT_NEAR(falloff_at(1.0), 1.0, 1e-6);
    EXPECT_NEAR(falloff_at(co + 1e-4), 1.0, 1e-5);
    EXPECT_EQ(falloff_at(co - 1e-4), 0.0);
  }
  SceneDescription s;
  AddSphere(s, Vec3(0.0f), 3.0f, 5, AddMaterial(s, Material{.diffuse_reflectance = Rgb(0.5f)}), true,
            kNoLight, false);
  spot.light = 0;
  s.punctual_lights = {spot};
  s.num_lights = 1;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  const Rgb power = spot.intensity * float(2 * M_PI * (1 - co));
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(lights.total_power()[c], power[c], 1e-5 * power[c]);
  PhotonTracerOptions o;
  o.photons = 20480;
  const PhotonTracingResult r = TracePhotons(accel, lights, o);
  ASSERT_EQ(r.direct.size(), size_t(o.photons));
  Rgb sum;
  for (const TracedPhoton& p : r.direct) {
    ASSERT_TRUE(p.power.IsFinite());
    sum += p.power;
    EXPECT_GE(Dot(Normalize(p.position - Vec3(spot.position)), spot.direction), co - 1e-3)
        << "a photon outside the cone";
  }
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(sum[c], power[c], 1e-3 * power[c]) << "channel " << c;
}

// A directional light's photons leave a disc of the bounding sphere's radius R with Φ = E⊥·π·R²
// in all: a tilted square of area A receives E⊥·A·cos θ of it.
TEST(PunctualLights, DirectionalPhotonsDeliverIrradianceTimesArea) {
  SceneDescription s;
  const uint32_t grey = AddMaterial(s, Material{.diffuse_reflectance = Rgb(0.5f)});
  AddQuad(s, {-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, grey);
  PunctualLight sun = DirectionalLight();
  s.punctual_lights = {sun};
  s.num_lights = 1;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  const float radius = 0.5f * Length(accel.bounds().Diagonal());
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(lights.total_power()[c], sun.intensity[c] * kPi * radius * radius, 1e-5 * 10);

  PhotonTracerOptions o;
  o.photons = 40960;
  const PhotonTracingResult r = TracePhotons(accel, lights, o);
  Rgb received;
  for (const TracedPhoton& p : r.direct) received += p.power;
  const double cos_theta = -sun.direction.z;
  std::printf("[ analytic ] directional photons on the square / (E·A·cos θ): %.5f\n",
              received.g / (sun.intensity.g * 4.0 * cos_theta));
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(received[c], sun.intensity[c] * 4.0 * cos_theta, 0.01 * sun.intensity[c] * 4.0 * cos_theta)
        << "channel " << c;
}

// A light id beyond the scene's num_lights would silently take the slot of the triangles without
// an id (photon-direct's light of such photons): a scene built wrongly is refused instead.
TEST(PunctualLights, AnIdBeyondTheScenesLightsIsRefused) {
  SceneDescription s = testing::FloorUnderSquareLight(0.5f);
  s.punctual_lights = {PointLight()};
  s.punctual_lights[0].light = s.num_lights + 3;
  s.num_lights += 1;
  const EmbreeScene accel(s);
  EXPECT_THROW(LightSampler lights(accel), std::logic_error);
  s.punctual_lights[0].light = s.num_lights - 1;
  const EmbreeScene fine(s);
  EXPECT_NO_THROW(LightSampler lights(fine));
}

// With an area light beside them, punctual lights add emitters after its triangles and keep its
// samples: the triangles come first in EmitterIndex's numbering and their light keeps number 0.
TEST(PunctualLights, AreaLightsKeepTheirNumbersBesideThem) {
  SceneDescription s = testing::FloorUnderSquareLight(0.5f);
  s.punctual_lights = {PointLight()};
  s.punctual_lights[0].light = s.num_lights++;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 2u);
  EXPECT_EQ(lights.LightIndex(0), 0u);
  EXPECT_EQ(lights.LightIndex(1), 1u);
  EXPECT_EQ(lights.num_emitters(), lights.num_emitting_triangles() + 1);
  EXPECT_FALSE(lights.EmitterSample(0, 0.5f, 0.5f).delta());
  EXPECT_TRUE(lights.EmitterSample(lights.num_emitting_triangles(), 0.5f, 0.5f).delta());
  EXPECT_TRUE(lights.SampleLight(1, 0.5f, 0.5f, 0.5f).delta());
  EXPECT_FALSE(lights.SampleLight(0, 0.5f, 0.5f, 0.5f).delta());
}

}  // namespace
}  // namespace pf
