// The environment light (common/lights/environment_light.h, common/scene/environment.h) against
// analytic values: a diffuse convex object under a uniform environment L renders ρ·L (every
// point sees the whole sky over its hemisphere, nothing else), with the path tracer and the
// photon map; a plane under a non-uniform sky renders ρ/π·E with E = ∫L cos θ dω by quadrature;
// the sampling distribution integrates to 1, matches the histogram of its samples and is
// ∝ luminance; the photons carry the environment's power; rotation moves a bright spot.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "common/lights/environment_light.h"
#include "common/lights/light_sampler.h"
#include "common/photon/photon_tracer.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "tests/common/furnace_local_pass.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

constexpr float kAlbedo = 0.5f;
const Rgb kSky(0.6f, 0.8f, 1.0f);

Environment ConstantEnvironment(const Rgb& color) {
  Environment e;
  e.color = color;
  return e;
}

// A W × H sky: a blue gradient darker towards the nadir, a bright 2 × 2 "sun" texel block
// around column W/4 in the upper half, and one black texel (pdf 0 there).
Environment ImageEnvironment(int w, int h, float rotation = 0.0f) {
  auto image = std::make_shared<Image>(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float up = 1.0f - float(y) / float(h);
      image->at(x, y) =
          Rgb(0.2f + 0.3f * up, 0.3f + 0.4f * up, 0.5f + 0.5f * up) * (0.5f + float(x % 3) * 0.25f);
    }
  for (int y = h / 4; y < h / 4 + 2; ++y)
    for (int x = w / 4; x < w / 4 + 2; ++x) image->at(x, y) = Rgb(200.0f, 180.0f, 150.0f);
  image->at(w - 1, h - 1) = Rgb(0.0f);
  Environment e;
  e.file = "sky.hdr";
  e.image = image;
  e.rotation_deg = rotation;
  return e;
}

// A flat-faceted sphere (convex, shading normal = geometric) of albedo ρ at the origin, lit by
// `environment` alone.
SceneDescription SphereUnder(const Environment& environment) {
  SceneDescription s;
  testing::AddSphere(s, Vec3(0.0f), 1.0f, 3,
                     testing::AddMaterial(s, Material{.diffuse_reflectance = Rgb(kAlbedo)}), false, kNoLight,
                     false);
  s.environment = environment;
  s.environment->light = 0;
  s.num_lights = 1;
  return s;
}

CameraSpec SphereCamera() {
  return testing::LookAtCamera(Vec3(0.3f, 0.5f, 3.5f), Vec3(0, 0, 0), Vec3(0, 1, 0), 45, 24, 24);
}

// Per pixel: 1 if all of an 8 × 8 grid of its camera rays hit the object, 0 if none does, −1 mixed.
std::vector<int> Coverage(const EmbreeScene& accel, const Camera& camera) {
  std::vector<int> out;
  for (int y = 0; y < camera.height(); ++y)
    for (int x = 0; x < camera.width(); ++x) {
      int hits = 0;
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i)
          hits += accel.Intersect(camera.GenerateRay(x, y, (i + 0.5f) / 8, (j + 0.5f) / 8)).has_value();
      out.push_back(hits == 64 ? 1 : hits == 0 ? 0 : -1);
    }
  return out;
}

// Object pixels (and their 8 neighbours) render ρ·L: their mean within 1 %, each within
// `pixel_tolerance` (the noise of one pixel's estimate); sky pixels (and their neighbours) L
// exactly (the camera sees it with weight 1).
void ExpectConvexFurnace(const Image& img, const std::vector<int>& coverage, const std::string& what,
                         double pixel_tolerance = 0.06) {
  const int w = img.width(), h = img.height();
  const auto same_around = [&](int x, int y, int value) {
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = std::clamp(x + dx, 0, w - 1), yy = std::clamp(y + dy, 0, h - 1);
        if (coverage[size_t(yy) * w + xx] != value) return false;
      }
    return true;
  };
  const Rgb want = kSky * kAlbedo;
  double sum[3] = {0, 0, 0};
  int object = 0, sky = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const Rgb& c = img.at(x, y);
      if (same_around(x, y, 1)) {
        ++object;
        for (int k = 0; k < 3; ++k) {
          sum[k] += c[k];
          EXPECT_NEAR(c[k], want[k], pixel_tolerance * want[k])
              << what << " object pixel (" << x << "," << y << ")";
        }
      } else if (same_around(x, y, 0)) {
        ++sky;
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(c[k], kSky[k], 1e-5 * kSky[k]) << what << " sky pixel";
      }
    }
  ASSERT_GT(object, 50) << what;
  ASSERT_GT(sky, 50) << what;
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(sum[k] / object, want[k], 0.01 * want[k]) << what << " channel " << k;
  std::printf("[ analytic ] %s: object mean / (rho L) = %.4f %.4f %.4f over %d pixels\n", what.c_str(),
              sum[0] / object / want[0], sum[1] / object / want[1], sum[2] / object / want[2], object);
}

TEST(EnvironmentLight, ConvexObjectUnderAUniformSkyIsAlbedoTimesL_PathTracer) {
  const SceneDescription s = SphereUnder(ConstantEnvironment(kSky));
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  ASSERT_NE(lights.environment(), nullptr);
  const Camera camera(SphereCamera());
  const Image img = RenderImage(PathTracer(accel, lights), camera, RenderOptions{.spp = 256, .seed = 3});
  ExpectConvexFurnace(img, Coverage(accel, camera), "path tracer");
}

TEST(EnvironmentLight, ConvexObjectUnderAUniformSkyIsAlbedoTimesL_PhotonMap) {
  const SceneDescription s = SphereUnder(ConstantEnvironment(kSky));
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  const Camera camera(SphereCamera());
  const std::vector<int> coverage = Coverage(accel, camera);
  // A convex object has no indirect light: with separate direct light the global map is empty.
  testing::ForEachSeparateDirectIntegrator(
      accel, lights, [&](const Integrator& integrator, const char* name) {
        ExpectConvexFurnace(RenderImage(integrator, camera, RenderOptions{.spp = 256, .seed = 3}), coverage,
                            name);
      });
  // Standalone (§2.5): the direct photons themselves, k-nearest density estimation (a pixel's
  // estimate has the noise of its k = 200 photons, about 7 %).
  PhotonMapIntegratorOptions io;
  io.global.k = 200;
  const PhotonMaps maps = testing::MapsFor(accel, lights, io, 400000, 5);
  ExpectConvexFurnace(
      RenderImage(PhotonMapIntegrator(accel, maps, io), camera, RenderOptions{.spp = 4, .seed = 3}), coverage,
      "photon map, photons only", 0.25);
}

// The radiance a Lambertian floor (normal +Y) reflects under `env`: ρ/π·∫_{y>0} L cos θ dω, by a
// midpoint rule over (cos θ, φ) — independent of the light's own tables.
Rgb FloorRadiance(const Environment& env) {
  constexpr int kZ = 1024, kPhi = 4096;
  double e[3] = {0, 0, 0};
  const double dz = 1.0 / kZ, dphi = 2 * M_PI / kPhi;
  for (int i = 0; i < kZ; ++i) {
    const double z = (i + 0.5) * dz;  // cos θ = y
    const double r = std::sqrt(1 - z * z);
    for (int j = 0; j < kPhi; ++j) {
      const double phi = (j + 0.5) * dphi;
      const Rgb l = env.Radiance(Vec3(float(r * std::cos(phi)), float(z), float(r * std::sin(phi))));
      for (int k = 0; k < 3; ++k) e[k] += l[k] * z * dz * dphi;
    }
  }
  return Rgb(float(e[0]), float(e[1]), float(e[2])) * (kAlbedo / kPi);
}

// A non-uniform sky with a small bright sun: light sampling finds the sun, BSDF sampling the
// broad sky; MIS must weigh them to exactly ρ/π·E.
TEST(EnvironmentLight, FloorUnderAnImageSkyIsRhoOverPiTimesIrradiance) {
  const Environment env = ImageEnvironment(64, 32, 30.0f);
  SceneDescription s;
  testing::AddQuad(s, {-20, 0, 20}, {20, 0, 20}, {20, 0, -20}, {-20, 0, -20},
                   testing::AddMaterial(s, Material{.diffuse_reflectance = Rgb(kAlbedo)}));
  s.environment = env;
  s.num_lights = 1;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  const Camera camera(testing::LookAtCamera(Vec3(0, 3, 0.01f), Vec3(0, 0, 0), Vec3(0, 0, -1), 40, 12, 12));
  const Rgb want = FloorRadiance(env);
  const auto check = [&](const Image& img, const std::string& what) {
    double sum[3] = {0, 0, 0};
    for (const Rgb& c : img.pixels())
      for (int k = 0; k < 3; ++k) sum[k] += c[k];
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(sum[k] / img.size(), want[k], 0.01 * want[k]) << what << " channel " << k;
    std::printf("[ analytic ] image sky, %s: floor mean / (rho/pi E) = %.4f\n", what.c_str(),
                sum[1] / img.size() / want.g);
  };
  check(RenderImage(PathTracer(accel, lights), camera, RenderOptions{.spp = 256, .seed = 7}), "path tracer");
  PhotonMapIntegratorOptions io;
  io.direct = DirectLightMode::kMonteCarlo;
  const PhotonMaps maps = testing::MapsFor(accel, lights, io, 20000, 5);
  check(RenderImage(PhotonMapIntegrator(accel, &lights, maps, io), camera,
                    RenderOptions{.spp = 256, .seed = 7}),
        "photon map, Monte Carlo direct");
}

// ∫ pdf dω = 1 by a midpoint rule over (cos θ, φ), and pdf ∝ luminance cell by cell: pdf(ω) =
// lum(L(ω)) / ∫ lum(L) dω.
TEST(EnvironmentLight, PdfIntegratesToOneAndFollowsLuminance) {
  for (const float rotation : {0.0f, 75.0f}) {
    const Environment env = ImageEnvironment(16, 8, rotation);
    const EnvironmentLight light(env, Vec3(0.0f), 1.0f);
    constexpr int kZ = 1024, kPhi = 2048;
    const double dz = 2.0 / kZ, dphi = 2 * M_PI / kPhi;
    double integral = 0;
    for (int i = 0; i < kZ; ++i) {
      const double z = -1 + (i + 0.5) * dz, r = std::sqrt(1 - z * z);
      for (int j = 0; j < kPhi; ++j) {
        const double phi = (j + 0.5) * dphi;
        integral += light.Pdf(Vec3(float(r * std::cos(phi)), float(z), float(r * std::sin(phi)))) * dz * dphi;
      }
    }
    EXPECT_NEAR(integral, 1.0, 2e-3) << "rotation " << rotation;
    const double lum_integral = light.integrated_radiance().Luminance();
    for (int row = 0; row < env.height(); ++row)
      for (int col = 0; col < env.width(); ++col) {
        const float z = 0.5f * (env.RowZ(row) + env.RowZ(row + 1));
        const Vec3 wi = env.ToWorld(env.Direction(z, col, 0.5f));
        const double want = env.Texel(row, col).Luminance() / lum_integral;
        EXPECT_NEAR(light.Pdf(wi), want, 1e-4 * want + 1e-9) << "cell " << row << "," << col;
      }
    std::printf("[ analytic ] rotation %.0f: integral of the pdf over the sphere %.6f\n", rotation, integral);
  }
}

// 200k samples binned by cell against N·pdf·Δω (chi-square, cells expecting ≥ 5); every sample's
// pdf and radiance are those of its direction; no sample in the black cell.
TEST(EnvironmentLight, SamplesMatchThePdf) {
  const Environment env = ImageEnvironment(16, 8, 40.0f);
  const EnvironmentLight light(env, Vec3(0.0f), 1.0f);
  const int w = env.width(), h = env.height();
  std::vector<double> count(size_t(w * h), 0.0);
  constexpr int kN = 200000;
  Rng rng(11, 0);
  for (int n = 0; n < kN; ++n) {
    const EnvironmentLight::DirectionSample d = light.Sample(rng.Uniform(), rng.Uniform());
    ASSERT_NEAR(Length(d.wi), 1.0f, 1e-5f);
    ASSERT_EQ(d.pdf, light.Pdf(d.wi));
    ASSERT_GT(d.pdf, 0.0f);
    const Rgb l = light.Radiance(d.wi);
    ASSERT_TRUE(d.radiance.r == l.r && d.radiance.g == l.g && d.radiance.b == l.b);
    int row, col;
    env.Cell(env.ToLocal(d.wi), &row, &col);
    count[size_t(row * w + col)] += 1;
  }
  EXPECT_EQ(count[size_t(h * w - 1)], 0.0) << "a black texel is never sampled";
  double chi2 = 0;
  int dof = -1;
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const float z = 0.5f * (env.RowZ(row) + env.RowZ(row + 1));
      const double expected =
          kN * light.Pdf(env.ToWorld(env.Direction(z, col, 0.5f))) * env.CellSolidAngle(row);
      if (expected < 5) continue;
      chi2 +=
          (count[size_t(row * w + col)] - expected) * (count[size_t(row * w + col)] - expected) / expected;
      ++dof;
    }
  // Mean dof, standard deviation √(2·dof): 5σ above the mean fails.
  EXPECT_LT(chi2, dof + 5 * std::sqrt(2.0 * dof)) << "dof " << dof;
  std::printf("[ analytic ] sample histogram: chi-square %.1f for %d degrees of freedom\n", chi2, dof);
}

// A constant sky is sampled uniformly: pdf 1/(4π) everywhere.
TEST(EnvironmentLight, ConstantSkyIsSampledUniformly) {
  const EnvironmentLight light(ConstantEnvironment(kSky), Vec3(0.0f), 2.0f);
  for (const Vec3& d : {Vec3(0, 1, 0), Vec3(0, -1, 0), Normalize(Vec3(1, 2, 3)), Vec3(0, 0, -1)})
    EXPECT_NEAR(light.Pdf(d), 1.0 / (4 * M_PI), 1e-7);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(light.integrated_radiance()[k], 4 * M_PI * kSky[k], 1e-5 * 4 * M_PI);
    EXPECT_NEAR(light.power()[k], M_PI * 4.0 * 4 * M_PI * kSky[k], 1e-4 * 4 * M_PI * M_PI * 4);
  }
}

// Rotation by α about +Y: what sat at −Z (the image's centre) is seen at −X after 90°.
TEST(EnvironmentLight, RotationMovesTheBrightSpot) {
  auto image = std::make_shared<Image>(32, 16);
  for (int y = 7; y <= 8; ++y)
    for (int x = 15; x <= 16; ++x) image->at(x, y) = Rgb(100.0f);
  Environment env;
  env.file = "spot.hdr";
  env.image = image;
  EXPECT_EQ(env.Radiance(Vec3(0, 0, -1)).g, 100.0f);
  EXPECT_EQ(env.Radiance(Vec3(-1, 0, 0)).g, 0.0f);
  env.rotation_deg = 90.0f;
  EXPECT_EQ(env.Radiance(Vec3(0, 0, -1)).g, 0.0f);
  EXPECT_EQ(env.Radiance(Vec3(-1, 0, 0)).g, 100.0f);
  EXPECT_EQ(env.Radiance(Vec3(1, 0, 0)).g, 0.0f);
  // Its samples all come from around −X.
  const EnvironmentLight light(env, Vec3(0.0f), 1.0f);
  Rng rng(2, 0);
  for (int n = 0; n < 1000; ++n) EXPECT_LT(light.Sample(rng.Uniform(), rng.Uniform()).wi.x, -0.95f);
}

// Photon power (§2.2): the environment's photons carry π·R²·∫L dω in all; a convex object
// receives E = π·L on every point, π·L·A in all: its direct photons sum to that.
TEST(EnvironmentLight, PhotonPowerIsTheEnvironmentsPower) {
  const SceneDescription s = SphereUnder(ConstantEnvironment(kSky));
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  const float radius = 0.5f * Length(accel.bounds().Diagonal());
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(lights.total_power()[k], kSky[k] * 4 * M_PI * M_PI * radius * radius, 1e-5 * 100);
  double area = 0;
  for (uint32_t t = 0; t < s.triangles.size(); ++t) area += accel.triangle_area(t);
  PhotonTracerOptions o;
  o.photons = 200000;
  const PhotonTracingResult r = TracePhotons(accel, lights, o);
  Rgb received;
  for (const TracedPhoton& p : r.direct) {
    received += p.power;
    ASSERT_EQ(p.light, 0u);
  }
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(received[k], M_PI * kSky[k] * area, 0.01 * M_PI * kSky[k] * area) << "channel " << k;
  std::printf("[ analytic ] environment photons on a convex object / (pi L A): %.5f\n",
              received.g / (M_PI * kSky.g * area));
}

// Beside an area light the environment is the last emitter and the last light.
TEST(EnvironmentLight, IsTheLastEmitterAndLight) {
  SceneDescription s = testing::FloorUnderSquareLight(0.5f);
  s.environment = ConstantEnvironment(Rgb(0.1f));
  s.environment->light = s.num_lights++;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  ASSERT_EQ(lights.num_lights(), 2u);
  EXPECT_EQ(lights.LightIndex(1), 1u);
  EXPECT_EQ(lights.num_emitters(), lights.num_emitting_triangles() + 1);
  EXPECT_TRUE(lights.EmitterSample(lights.num_emitting_triangles(), 0.5f, 0.5f).environment);
  EXPECT_FALSE(lights.EmitterSample(0, 0.5f, 0.5f).environment);
  EXPECT_TRUE(lights.SampleLight(1, 0.5f, 0.5f, 0.5f).environment);
  // Chosen ∝ power: the environment's share of the total.
  const double env_power = lights.light_power(1).Luminance(), total = lights.total_power().Luminance();
  EXPECT_NEAR(lights.EmitterSample(lights.num_emitting_triangles(), 0.5f, 0.5f).pdf_area, env_power / total,
              1e-5);
}

}  // namespace
}  // namespace pf
