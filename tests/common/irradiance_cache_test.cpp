// Irradiance caching for the local pass (Ward et al. 1988; common/render/irradiance_cache.h):
// the interpolation against an analytic field, the trade of the error parameter, the furnace,
// and determinism of the per-block caches in the renderer.
#include "common/render/irradiance_cache.h"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include "common/camera/camera.h"
#include "common/core/rng.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"
#include "tests/common/furnace_local_pass.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::MapsFor;

// A plane z = 0 under a point light of intensity 1 at height h above the origin:
// E(x, y) = h / (x² + y² + h²)^{3/2}, smooth, changing by 1.5/h relative per unit at r = h.
constexpr float kLightHeight = 1.0f;
float PointLitIrradiance(float x, float y) {
  const float d2 = x * x + y * y + kLightHeight * kLightHeight;
  return kLightHeight / (d2 * std::sqrt(d2));
}

struct FieldResult {
  size_t records = 0;
  double max_relative_error = 0, rms_relative_error = 0;
};

// Fills a cache the way the renderer does — points in a fixed order, interpolate or else
// "gather" (here: the analytic value, with harmonic mean distance h) — over a 128×128 grid of
// [-2, 2]², and compares every interpolated value with the analytic field.
FieldResult FillPointLitPlane(float a) {
  IrradianceCacheOptions o;
  o.error = a;
  o.min_radius = 0.01f;
  o.max_radius = 10.0f;
  IrradianceCache cache(o);
  const Vec3 n(0, 0, 1);
  FieldResult r;
  double sum2 = 0;
  int interpolated = 0;
  constexpr int kSide = 128;
  for (int j = 0; j < kSide; ++j) {
    for (int i = 0; i < kSide; ++i) {
      const float x = -2.0f + 4.0f * (float(i) + 0.5f) / kSide, y = -2.0f + 4.0f * (float(j) + 0.5f) / kSide;
      const float exact = PointLitIrradiance(x, y);
      if (const std::optional<Rgb> e = cache.Interpolate(Vec3(x, y, 0), n)) {
        const double rel = std::abs(double(e->g) - exact) / exact;
        r.max_relative_error = std::max(r.max_relative_error, rel);
        sum2 += rel * rel;
        ++interpolated;
      } else {
        cache.Add(Vec3(x, y, 0), n, Rgb(exact), /*inverse_distance_sum=*/8.0 / kLightHeight, /*hits=*/8);
      }
    }
  }
  r.records = cache.records().size();
  r.rms_relative_error = interpolated > 0 ? std::sqrt(sum2 / interpolated) : 0.0;
  return r;
}

// Ward's weighted mean (no gradients) reproduces the smooth field with an error proportional to
// a: the field changes by up to 1.5 relative per R, so by 1.5·a over a record's reach a·R, and
// in raster order a point is often served by records on one side only (extrapolation). Bounds:
// max relative error < 2·a, RMS < 0.6·a (measured for a = 0.4 / 0.2 / 0.1 / 0.05: max 0.77 /
// 0.32 / 0.12 / 0.049, RMS 0.200 / 0.101 / 0.049 / 0.029), with 2.5 % of the points gathering
// at a = 0.2.
TEST(IrradianceCache, InterpolationReproducesThePointLitPlane) {
  const FieldResult r = FillPointLitPlane(0.2f);
  EXPECT_LT(r.records, 128u * 128u * 3u / 100u);
  EXPECT_LT(r.max_relative_error, 2 * 0.2);
  EXPECT_LT(r.rms_relative_error, 0.6 * 0.2);
}

// The error parameter trades records (gathers) for error, monotonically.
TEST(IrradianceCache, SmallerErrorParameterMeansMoreRecordsAndLessError) {
  FieldResult previous = FillPointLitPlane(0.4f);
  for (float a : {0.2f, 0.1f, 0.05f}) {
    const FieldResult r = FillPointLitPlane(a);
    EXPECT_GT(r.records, previous.records) << "a = " << a;
    EXPECT_LT(r.max_relative_error, previous.max_relative_error) << "a = " << a;
    EXPECT_LT(r.rms_relative_error, previous.rms_relative_error) << "a = " << a;
    EXPECT_LT(r.max_relative_error, 2 * a) << "a = " << a;
    EXPECT_LT(r.rms_relative_error, 0.6 * a) << "a = " << a;
    previous = r;
  }
}

// A record never serves a point whose normal turned away (sqrt(1 − cos) ≥ a) or that lies
// behind it (the record's point in front of x's tangent plane: it may see what x does not).
TEST(IrradianceCache, NormalsAndInFrontTestRejectRecords) {
  IrradianceCacheOptions o;
  o.error = 0.3f;
  o.min_radius = 0.01f;
  o.max_radius = 10.0f;
  IrradianceCache cache(o);
  cache.Add(Vec3(0, 0, 0), Vec3(0, 0, 1), Rgb(2.0f), 1.0, 1);  // R = 1
  ASSERT_TRUE(cache.Interpolate(Vec3(0.1f, 0, 0), Vec3(0, 0, 1)).has_value());
  EXPECT_FLOAT_EQ(cache.Interpolate(Vec3(0.1f, 0, 0), Vec3(0, 0, 1))->g, 2.0f);
  EXPECT_FALSE(cache.Interpolate(Vec3(0.4f, 0, 0), Vec3(0, 0, 1)).has_value());  // too far: 0.4/1
  const float tilt = 0.5f;                                                       // sqrt(1 − cos 0.5) = 0.34
  EXPECT_FALSE(cache.Interpolate(Vec3(0, 0, 0), Vec3(std::sin(tilt), 0, std::cos(tilt))).has_value());
  EXPECT_FALSE(cache.Interpolate(Vec3(0, 0, -0.1f), Vec3(0, 0, 1)).has_value());  // x behind the record
  EXPECT_TRUE(cache.Interpolate(Vec3(0, 0, 0.1f), Vec3(0, 0, 1)).has_value());    // x in front is fine
}

// The hashed grid finds exactly the records a scan over all of them finds, and sums them in the
// same order: bit-identical results for records of every radius level (R from the clamp's
// minimum to its maximum), normals on three planes and points on and off them. Removing the
// reach's padding in Add, or filing a record in fewer cells, makes lookups near a reach's edge
// miss a record (the scan finds it) and fails this.
TEST(IrradianceCache, GridLookupEqualsTheLinearScan) {
  for (const float a : {0.05f, 0.2f, 0.6f}) {
    IrradianceCacheOptions o;
    o.error = a;
    o.min_radius = 0.01f;
    o.max_radius = 0.25f;
    IrradianceCache cache(o);
    Rng rng(7, 11);
    const Vec3 normals[] = {Vec3(0, 0, 1), Vec3(0, 1, 0), Normalize(Vec3(1, 1, 0.2f))};
    auto point = [&] { return Vec3(rng.Uniform() - 0.5f, rng.Uniform() - 0.5f, 0.05f * rng.Uniform()); };
    for (int i = 0; i < 2000; ++i) {
      // 1/R from 1/0.005 to 1/0.5: clamped at both ends, and every level between.
      const double inverse_r = std::exp(std::log(2.0) + rng.UniformDouble() * std::log(100.0));
      cache.Add(point(), normals[i % 3], Rgb(rng.Uniform(), rng.Uniform(), rng.Uniform()), inverse_r, 1);
    }
    int found = 0;
    for (int q = 0; q < 20000; ++q) {
      // Half the queries near a record (within 1.2 of its reach), half anywhere.
      const IrradianceRecord& near = cache.records()[rng.UniformInt(uint32_t(cache.records().size()))];
      const Vec3 offset =
          Vec3(rng.Uniform() - 0.5f, rng.Uniform() - 0.5f, rng.Uniform() - 0.5f) * (2.4f * a * near.radius);
      const Vec3 x = q % 2 == 0 ? near.position + offset : point();
      const Vec3 n = q % 4 < 2 ? near.normal : normals[rng.UniformInt(3)];
      const std::optional<Rgb> grid = cache.Interpolate(x, n), scan = cache.InterpolateLinearScan(x, n);
      ASSERT_EQ(grid.has_value(), scan.has_value()) << "a " << a << " query " << q;
      if (!grid) continue;
      ++found;
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(std::bit_cast<uint32_t>((*grid)[c]), std::bit_cast<uint32_t>((*scan)[c]));
    }
    EXPECT_GT(found, 1000) << "a " << a << ": too few lookups found a record to test anything";
  }
}

// The local pass with the cache in the furnace (albedo 0.8, Le = 1): every pixel Le/(1−a) = 5
// within 6 % and the image mean within 1 %. Each pixel interpolates a few records of 16 gather
// rays each, so their photon noise remains: over seeds 2–5 the 16 pixels' standard deviation was
// 0.042–0.077 (0.8–1.5 %) and the largest deviation 0.155, so 0.3 is a 4σ bound per pixel; the
// mean's bound 0.05 is > 3σ (σ ≈ 0.077/4). A wrong ρ or π factor in
// the cached E/π (or a record gathered with the material's weights) fails it.
TEST(IrradianceCacheRender, FurnaceAnalyticValue) {
  const SceneDescription s = testing::FurnaceScene(0.8f);
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  for (DirectLightMode mode : {DirectLightMode::kNone, DirectLightMode::kMonteCarlo}) {
    PhotonMapIntegratorOptions io = testing::FurnaceLocalPassOptions(mode);
    io.irradiance_cache.error = 0.3f;
    const PhotonMaps maps = MapsFor(accel, lights, io, 200000, 4, 2);
    const PhotonMapIntegrator integrator(accel, &lights, maps, io);
    RenderStats stats;
    const Image img = RenderImage(integrator, Camera(testing::FurnaceCamera()),
                                  RenderOptions{.spp = 16, .seed = 2}, &stats);
    double mean = 0;
    for (size_t i = 0; i < img.size(); ++i) {
      EXPECT_NEAR(img[i].Mean(), 5.0f, 0.3f) << "pixel " << i << " direct mode " << int(mode);
      mean += img[i].Mean() / double(img.size());
    }
    EXPECT_NEAR(mean, 5.0, 0.05) << "direct mode " << int(mode);
    EXPECT_GT(stats.counters.cache_interpolations, 0u);
    EXPECT_LT(stats.counters.gathers, img.size() * 16 / 4);
  }
}

class IrradianceCacheCornell : public ::testing::Test {
 protected:
  IrradianceCacheCornell()
      : scene_(LoadScene(std::filesystem::path(PF_SOURCE_DIR) / "scenes/cornell-box/cornell-box.json")),
        accel_(scene_),
        lights_(accel_) {
    io_.global.k = 30;
    io_.direct = DirectLightMode::kMonteCarlo;
    io_.monte_carlo.shadow_rays = 2;
    io_.direct_photons = DefaultDirectPhotonOptions(io_.global, accel_.bounds());
    io_.caustic = DefaultCausticOptions(30, accel_.bounds());
    io_.local_pass_rays = 8;  // Render's default
    maps_ = std::make_unique<PhotonMaps>(MapsFor(accel_, lights_, io_, 20000, 5, 2));
    camera_ = scene_.cameras.front();
    camera_.width = camera_.height = 48;  // 3×3 blocks of 16×16
  }

  Image Render(float error, int threads, RenderStats* stats = nullptr, int gather_rays = 8) const {
    PhotonMapIntegratorOptions io = io_;
    io.irradiance_cache.error = error;
    io.local_pass_rays = gather_rays;
    const PhotonMapIntegrator integrator(accel_, &lights_, *maps_, io);
    return RenderImage(integrator, Camera(camera_), RenderOptions{.spp = 2, .seed = 9, .threads = threads},
                       stats);
  }

  SceneDescription scene_;
  EmbreeScene accel_;
  LightSampler lights_;
  PhotonMapIntegratorOptions io_;
  std::unique_ptr<PhotonMaps> maps_;
  CameraSpec camera_;
};

bool BitIdentical(const Image& a, const Image& b) {
  return a.size() == b.size() &&
         std::memcmp(a.pixels().data(), b.pixels().data(), a.size() * sizeof(Rgb)) == 0;
}

// One cache per 16×16 block, filled in pixel order by one thread: 1 and 2 threads give the
// same bits, and the cache is really on (the image differs from the uncached local pass).
TEST_F(IrradianceCacheCornell, BitIdenticalForOneAndTwoThreads) {
  const Image one = Render(0.2f, 1);
  const Image two = Render(0.2f, 2);
  EXPECT_TRUE(BitIdentical(one, two));
  EXPECT_FALSE(BitIdentical(one, Render(0.0f, 2)));
}

// The cache skips most gathers, and a smaller error parameter buys more gathers and less error.
// The error is the cache's own: the difference to the uncached local pass with the same seed,
// samples and map — where a point gathers, both send the same rays (the white lobe samples the
// directions the material's diffuse lobe would), so the photon map's and the gather's noise
// cancel and what remains is the interpolation and the records' own gather noise, which it
// spreads (32 rays per gather keep that below the interpolation error; with 8 rays a = 0.4 and
// 0.2 measure alike). Measured (48², 2 spp; a = 0.4 / 0.2 / 0.1): gathers 467 / 1116 / 2160 of
// 4608 samples, RMSE 0.0051 / 0.0041 / 0.0029.
TEST_F(IrradianceCacheCornell, SkipsGathersAndTheErrorParameterTradesCountForError) {
  RenderStats full_stats;
  const Image full = Render(0.0f, 2, &full_stats, 32);
  const size_t pixels = full.size();
  EXPECT_EQ(full_stats.counters.cache_interpolations, 0u);
  EXPECT_GT(full_stats.counters.gathers, pixels * 2 * 9 / 10);  // all but the light's pixels

  auto rmse = [&](const Image& img) {
    double se = 0;
    for (size_t i = 0; i < pixels; ++i)
      se += double(img[i].Mean() - full[i].Mean()) * (img[i].Mean() - full[i].Mean());
    return std::sqrt(se / double(pixels));
  };
  uint64_t previous_gathers = 0;
  double previous_error = 1e9;
  for (float a : {0.4f, 0.2f, 0.1f}) {
    RenderStats stats;
    const Image img = Render(a, 2, &stats, 32);
    const double error = rmse(img);
    if (a >= 0.2f) {
      EXPECT_LT(stats.counters.gathers, pixels) << "a = " << a;
    }
    EXPECT_GT(stats.counters.gathers, previous_gathers) << "a = " << a;
    EXPECT_LT(error, previous_error) << "a = " << a;
    previous_gathers = stats.counters.gathers;
    previous_error = error;
  }
}

}  // namespace
}  // namespace pf
