// RenderPixels' random-number streams (common/render/renderer.h, PixelStreams): per pixel
// (independent pixels) or shared by every pixel of a call (common random numbers for the
// hierarchical plan's details, Wald 1999, §4.5). Emitters seen directly (renderer.h): the split
// estimate of the first hit's emission is unbiased against the analytic pixel value, far less
// noisy than one ray per sample, and absent where the pixel's lattice sees no emitter.
#include "common/render/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/render/path_tracer.h"
#include "common/sampling/sample_layout.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

// Returns the sampler's numbers as the colour: the sub-pixel offset and a light-sample slot.
class SamplerEcho final : public Integrator {
 public:
  Rgb Li(const Ray& /*ray*/, Sampler& sampler, TraceCounters& /*counters*/) const override {
    const Sample2 uv = sampler.Get2D(kPixelSlot);
    const float light = sampler.Get1D(kPixelSlot + 1);
    return Rgb(uv.u, uv.v, light);
  }
  const char* name() const override { return "sampler-echo"; }
};

CameraSpec SmallCamera(int w, int h) {
  CameraSpec spec;
  spec.eye = Vec3(0, 0, 1);
  spec.look_at = Vec3(0, 0, 0);
  spec.up = Vec3(0, 1, 0);
  spec.width = w;
  spec.height = h;
  return spec;
}

TEST(RenderPixelsStreams, SharedStreamsGiveEveryPixelTheSameNumbersPerPixelStreamsDoNot) {
  const Camera camera(SmallCamera(16, 16));
  const SamplerEcho echo;
  const std::vector<uint32_t> pixels = {0, 1, 17, 100, 255};
  for (SamplerKind kind : {SamplerKind::kSobol, SamplerKind::kIndependent}) {
    std::vector<Rgb> shared(pixels.size()), own(pixels.size());
    RenderPixels(echo, camera, pixels, 0, 3, 42, 1, shared, nullptr, nullptr, kind, PixelStreams::kShared);
    RenderPixels(echo, camera, pixels, 0, 3, 42, 1, own, nullptr, nullptr, kind, PixelStreams::kPerPixel);
    int differing = 0;
    for (size_t i = 1; i < pixels.size(); ++i) {
      EXPECT_EQ(shared[i].r, shared[0].r) << i;
      EXPECT_EQ(shared[i].g, shared[0].g) << i;
      EXPECT_EQ(shared[i].b, shared[0].b) << i;
      differing += own[i].r != own[0].r || own[i].b != own[0].b;
    }
    EXPECT_EQ(differing, int(pixels.size()) - 1) << "independent pixels must draw different numbers";
    // The shared stream depends on the seed (each detail task's map has its own pixel seed).
    std::vector<Rgb> other(1);
    RenderPixels(echo, camera, std::vector<uint32_t>{0}, 0, 3, 43, 1, other, nullptr, nullptr, kind,
                 PixelStreams::kShared);
    EXPECT_NE(other[0].r, shared[0].r);
  }
}

// The point of the shared streams: a detail f(p) − ½(f(a) + f(b)) of a smooth image (a Lambertian
// floor under a small area light, Monte Carlo direct light) has far less variance when p, a and b
// use the same random numbers. With independent streams its variance is about (1 + ¼ + ¼) σ² (σ²
// the per-pixel variance); with shared ones only what differs between the three pixels remains.
// 400 seeds: the variance estimates are good to about ±15 %, so the bound 0.1 has a wide margin
// against the measured ratio (5e-4: detail variance 8e-6 against 0.016) and could not pass with
// independent streams (≈ 1).
TEST(RenderPixelsStreams, SharedStreamsMakeADetailOfASmoothImageCancel) {
  const SceneDescription scene = testing::FloorUnderSquareLight(0.3f);
  const Camera camera(testing::FloorCamera());
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  const PathTracer tracer(accel, lights);
  // A midpoint p = (18, 20) between a = (16, 20) and b = (20, 20), all on the lit floor.
  const std::vector<uint32_t> pixels = {20 * 32 + 16, 20 * 32 + 18, 20 * 32 + 20};
  auto detail_variance = [&](PixelStreams streams, double* pixel_variance) {
    constexpr int kSeeds = 400;
    double s = 0, s2 = 0, p = 0, p2 = 0;
    for (int seed = 1; seed <= kSeeds; ++seed) {
      std::vector<Rgb> sums(pixels.size());
      RenderPixels(tracer, camera, pixels, 0, 1, uint64_t(seed), 1, sums, nullptr, nullptr,
                   SamplerKind::kSobol, streams);
      const double d = sums[1].Mean() - 0.5 * (sums[0].Mean() + sums[2].Mean());
      s += d;
      s2 += d * d;
      p += sums[1].Mean();
      p2 += sums[1].Mean() * sums[1].Mean();
    }
    *pixel_variance = (p2 - p * p / kSeeds) / (kSeeds - 1);
    return (s2 - s * s / kSeeds) / (kSeeds - 1);
  };
  double sigma2_own = 0, sigma2_shared = 0;
  const double own = detail_variance(PixelStreams::kPerPixel, &sigma2_own);
  const double shared = detail_variance(PixelStreams::kShared, &sigma2_shared);
  ASSERT_GT(sigma2_own, 0.0) << "the pixels must be noisy for the test to say anything";
  // Independent: the propagation (1.5 σ²) holds, within the estimate's error.
  EXPECT_NEAR(own / sigma2_own, 1.5, 0.4);
  // Each pixel alone is as noisy either way (the same estimator, other random numbers) ...
  EXPECT_NEAR(sigma2_shared / sigma2_own, 1.0, 0.35);
  // ... but the detail's noise cancels.
  EXPECT_LT(shared, 0.1 * own) << "shared " << shared << " own " << own;
}

// A light filling the view beyond x/(-z) = `edge` (a vertical line in the image), radiance 10,
// in front of a constant 0.5: Li = PrimaryEmission + 0.5, as the contract asks.
class HalfPlaneLight final : public Integrator {
 public:
  HalfPlaneLight(float edge, bool split) : edge_(edge), split_(split) {}
  Rgb Li(const Ray& ray, Sampler& /*sampler*/, TraceCounters& counters) const override {
    bool surface = false;
    return PrimaryEmission(ray, counters, &surface) + Rgb(0.5f);
  }
  bool SplitsPrimaryEmission() const override { return split_; }
  Rgb PrimaryEmission(const Ray& ray, TraceCounters& /*counters*/, bool* surface_emitter) const override {
    *surface_emitter = ray.direction.x / -ray.direction.z > edge_;
    return *surface_emitter ? Rgb(10.0f) : Rgb(0.0f);
  }
  const char* name() const override { return "half-plane-light"; }

 private:
  float edge_;
  bool split_;
};

// Pixel (7, 7) of a 15 × 15 image, 4 independent samples, over `seeds` seeds: its values.
std::vector<double> EdgePixelValues(const HalfPlaneLight& light, int seeds) {
  const Camera camera(SmallCamera(15, 15));
  std::vector<double> values;
  for (int seed = 1; seed <= seeds; ++seed) {
    std::vector<Rgb> sum(1);
    RenderPixels(light, camera, std::vector<uint32_t>{7 * 15 + 7}, 0, 4, uint64_t(seed), 1, sum, nullptr,
                 nullptr, SamplerKind::kIndependent);
    values.push_back(sum[0].r / 4.0);
  }
  return values;
}

double Mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return s / double(v.size());
}
double Variance(const std::vector<double>& v) {
  const double m = Mean(v);
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return s / double(v.size() - 1);
}

// The edge at u = `u` inside pixel 7 (x/(-z) is linear in u and independent of v for this camera).
float EdgeAt(float u) {
  const Ray r = Camera(SmallCamera(15, 15)).GenerateRay(7, 7, u, 0.5f);
  return r.direction.x / -r.direction.z;
}

// The light covers 70 % of the pixel: its value is 0.5 + 0.7 · 10 = 7.5. With one ray per sample
// the coverage noise is 10² · 0.21 / 4 ≈ 5.3 in variance; split, only the strata the edge crosses
// are random (16 rays per sample, one column of 4 crossed): about 1/80 of that. 400 seeds.
TEST(EmittersSeenDirectly, TheSplitEstimateIsUnbiasedAndFarLessNoisy) {
  const float edge = EdgeAt(0.3f);
  const std::vector<double> split = EdgePixelValues(HalfPlaneLight(edge, true), 400);
  const std::vector<double> plain = EdgePixelValues(HalfPlaneLight(edge, false), 400);
  for (const auto* values : {&split, &plain}) {
    const double stderr_of_mean = std::sqrt(Variance(*values) / double(values->size()));
    EXPECT_NEAR(Mean(*values), 7.5, 4 * stderr_of_mean + 1e-4) << (values == &split ? "split" : "plain");
  }
  EXPECT_NEAR(Variance(plain), 10.0 * 10.0 * 0.21 / 4, 1.5);
  EXPECT_LT(Variance(split), 0.05 * Variance(plain))
      << "split " << Variance(split) << " plain " << Variance(plain);
}

// Where the pixel's 2 × 2 lattice (u, v in {¼, ¾}) sees no emitter, nothing is split: the light
// covering u > 0.8 is rendered exactly as without the split — and still without bias.
TEST(EmittersSeenDirectly, APixelWhoseLatticeSeesNoEmitterIsRenderedAsBefore) {
  const float edge = EdgeAt(0.8f);
  const std::vector<double> split = EdgePixelValues(HalfPlaneLight(edge, true), 200);
  const std::vector<double> plain = EdgePixelValues(HalfPlaneLight(edge, false), 200);
  EXPECT_EQ(split, plain);
  EXPECT_NEAR(Mean(plain), 0.5 + 0.2 * 10, 4 * std::sqrt(Variance(plain) / 200.0));
}

}  // namespace
}  // namespace pf
