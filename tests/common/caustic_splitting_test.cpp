// Caustic splitting (Wald 1999, §4.6; common/photon/photon_tracer.h): brute force and Metropolis
// keep the caustic map's stored power (and brute force the global map's) within the statistical
// tolerance of independent seeds, put S× the photons into the caustic map, change nothing at
// S = 1, give the same photons for any thread count, and a map traced in pieces is still the map
// one process builds.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <vector>

#include "common/camera/camera.h"
#include "common/photon/photon_chunk.h"
#include "common/photon/photon_maps_bytes.h"
#include "common/photon/photon_tracer.h"
#include "common/plan/task_executor.h"
#include "common/render/scene_runtime.h"
#include "common/scene/scene_loader.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;
using testing::AddSphere;

// A glass sphere (ior 1.5) between a ceiling light and a floor, with a diffuse wall beside it:
// caustic chains start at the light (L S S D) and at the wall (L D S S D), and some photons
// reflect off the sphere (Fresnel) onto the wall and floor.
SceneDescription GlassSphereScene() {
  SceneDescription s;
  const uint32_t floor = AddMaterial(s, Material{.diffuse_reflectance = Rgb(0.5f)});
  const uint32_t wall = AddMaterial(s, Material{.diffuse_reflectance = Rgb(0.7f)});
  const uint32_t glass = AddMaterial(s, Material{.specular_transmittance = Rgb(1.0f), .ior = 1.5f});
  const uint32_t light = AddMaterial(s, Material{.emission = Rgb(10.0f)});
  AddQuad(s, {-4, -4, 0}, {4, -4, 0}, {4, 4, 0}, {-4, 4, 0}, floor);
  AddQuad(s, {1.5f, -4, 0}, {1.5f, -4, 3}, {1.5f, 4, 3}, {1.5f, 4, 0}, wall);  // faces -x
  AddSphere(s, {0, 0, 1}, 0.5f, 4, glass, false);
  AddQuad(s, {-0.5f, -0.5f, 3}, {-0.5f, 0.5f, 3}, {0.5f, 0.5f, 3}, {0.5f, -0.5f, 3}, light, 0);  // faces down
  s.num_lights = 1;
  return s;
}

struct Scene {
  Scene() : description(GlassSphereScene()), accel(description), lights(accel) {}
  SceneDescription description;
  EmbreeScene accel;
  LightSampler lights;
};

double Sum(const TracedPhotons& list) {
  double sum = 0;
  for (const TracedPhoton& p : list) sum += double(p.power.r) + p.power.g + p.power.b;
  return sum;
}

// The tracer's options for `photons` photons of map seed `seed`, split S = `split` by `method`.
PhotonTracerOptions TracerOptions(uint64_t photons, uint64_t seed, uint32_t split = 1,
                                  CausticSplitMethod method = CausticSplitMethod::kBrute) {
  PhotonTracerOptions o;
  o.photons = photons;
  o.map_seed = seed;
  o.caustic_split = split;
  o.caustic_split_method = method;
  return o;
}

// Stored caustic and non-caustic power of each seed's map.
struct PowerSamples {
  std::vector<double> caustic, global;
  double caustic_photons = 0;  // mean count
};

PowerSamples Measure(const Scene& scene, uint64_t photons, uint32_t split, CausticSplitMethod method,
                     int seeds) {
  PowerSamples out;
  for (int seed = 0; seed < seeds; ++seed) {
    const PhotonTracerOptions o = TracerOptions(photons, 1000 + uint64_t(seed), split, method);
    const PhotonTracingResult r = TracePhotons(scene.accel, scene.lights, o);
    out.caustic.push_back(Sum(r.caustic));
    out.global.push_back(Sum(r.direct) + Sum(r.indirect));
    out.caustic_photons += double(r.caustic.size()) / seeds;
  }
  return out;
}

// Mean of a − b over paired seeds and its standard error (pairing removes what the two maps of a
// seed share: Metropolis's walks are those without splitting).
struct Difference {
  double mean = 0, standard_error = 0, mean_b = 0;
};
Difference Paired(const std::vector<double>& a, const std::vector<double>& b) {
  Difference d;
  const double n = double(a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    d.mean += (a[i] - b[i]) / n;
    d.mean_b += b[i] / n;
  }
  double var = 0;
  for (size_t i = 0; i < a.size(); ++i) var += (a[i] - b[i] - d.mean) * (a[i] - b[i] - d.mean) / (n - 1);
  d.standard_error = std::sqrt(var / n);
  return d;
}

// The caustic map's stored power with splitting equals that without, within 4 standard errors
// of the paired difference over 8 independent seeds; brute force's global map too. The bounds
// are checked to be tight (< 2.5 % of the value), so a weighting error of a few percent — the
// power not divided by S, or by S + 1, or Metropolis without the Hastings ratio — fails. Brute
// force stores S× the caustic photons (±10 %: which photons become caustic is random);
// Metropolis stores one photon per distinct state (a rejected mutation raises the current
// state's weight instead), 1 + (S − 1)·acceptance per chain.
TEST(CausticSplitting, StoredPowerUnchangedWithinStatisticalTolerance) {
  const Scene scene;
  constexpr int kSeeds = 8;
  constexpr uint64_t kPhotons = 40000;
  constexpr uint32_t kSplit = 8;
  const PowerSamples none = Measure(scene, kPhotons, 1, CausticSplitMethod::kBrute, kSeeds);
  ASSERT_GT(none.caustic_photons, 1000.0);
  for (CausticSplitMethod method : {CausticSplitMethod::kBrute, CausticSplitMethod::kMetropolis}) {
    SCOPED_TRACE(CausticSplitMethodName(method));
    const PowerSamples split = Measure(scene, kPhotons, kSplit, method, kSeeds);
    const Difference c = Paired(split.caustic, none.caustic), g = Paired(split.global, none.global);
    std::printf("%s: caustic %+.3g ± %.2g of %.5g (%.0f photons, none %.0f); global %+.3g ± %.2g of %.5g\n",
                CausticSplitMethodName(method), c.mean, c.standard_error, c.mean_b, split.caustic_photons,
                none.caustic_photons, g.mean, g.standard_error, g.mean_b);
    EXPECT_LT(4.0 * c.standard_error, 0.025 * c.mean_b) << "the tolerance must be able to see a few percent";
    EXPECT_NEAR(c.mean, 0.0, 4.0 * c.standard_error);
    EXPECT_LT(4.0 * g.standard_error, 0.025 * g.mean_b);
    if (method == CausticSplitMethod::kBrute) {
      EXPECT_NEAR(g.mean, 0.0, 4.0 * g.standard_error);
      EXPECT_NEAR(split.caustic_photons / none.caustic_photons, double(kSplit), 0.1 * kSplit);
    } else {
      EXPECT_EQ(g.mean, 0.0) << "Metropolis must not touch the global map";
      EXPECT_GT(split.caustic_photons / none.caustic_photons, 1.0 + 0.5 * (kSplit - 1));
      EXPECT_LE(split.caustic_photons / none.caustic_photons, double(kSplit));
    }
  }
}

// Field by field (bit patterns of the floats): TracedPhoton has padding, which memcmp would compare.
bool Same(const TracedPhotons& a, const TracedPhotons& b) {
  if (a.size() != b.size()) return false;
  auto bits = [](const TracedPhoton& p) {
    std::array<uint32_t, 14> w{};
    std::memcpy(&w[0], &p.position, 12);
    std::memcpy(&w[3], &p.direction, 12);
    std::memcpy(&w[6], &p.power, 12);
    std::memcpy(&w[9], &p.origin, 12);
    w[12] = p.light;
    w[13] = uint32_t(p.kind);
    return w;
  };
  for (size_t i = 0; i < a.size(); ++i)
    if (bits(a[i]) != bits(b[i])) return false;
  return true;
}

// Metropolis leaves the global map alone (the same walks): bit-identical non-caustic photons.
// Brute force keeps one of S photons' non-caustic stores: the global map has about N photons'
// worth of stores (±5 %), not S·N.
TEST(CausticSplitting, GlobalMapKeepsItsSize) {
  const Scene scene;
  PhotonTracerOptions o = TracerOptions(20000, 3);
  const PhotonTracingResult none = TracePhotons(scene.accel, scene.lights, o);
  o.caustic_split = 6;
  o.caustic_split_method = CausticSplitMethod::kMetropolis;
  const PhotonTracingResult metropolis = TracePhotons(scene.accel, scene.lights, o);
  EXPECT_TRUE(Same(none.indirect, metropolis.indirect));
  EXPECT_EQ(none.direct.size(), metropolis.direct.size());
  EXPECT_GT(metropolis.chains, 1000u);
  EXPECT_EQ(metropolis.mutations, metropolis.chains * 5);
  EXPECT_GT(metropolis.accepted, metropolis.mutations / 4)
      << "the jitter should mostly keep the characteristic";
  EXPECT_EQ(metropolis.emitted, o.photons);
  o.caustic_split_method = CausticSplitMethod::kBrute;
  const PhotonTracingResult brute = TracePhotons(scene.accel, scene.lights, o);
  EXPECT_EQ(brute.emitted, 6 * o.photons);
  const double ratio =
      double(brute.direct.size() + brute.indirect.size()) / double(none.direct.size() + none.indirect.size());
  EXPECT_NEAR(ratio, 1.0, 0.05);
}

// S = 1 is no splitting, bit for bit, with either method.
TEST(CausticSplitting, SplitOfOneIsBitIdenticalToNoSplitting) {
  const Scene scene;
  PhotonTracerOptions o = TracerOptions(10000, 11);
  const PhotonTracingResult none = TracePhotons(scene.accel, scene.lights, o);
  for (CausticSplitMethod method : {CausticSplitMethod::kBrute, CausticSplitMethod::kMetropolis}) {
    o.caustic_split = 1;
    o.caustic_split_method = method;
    const PhotonTracingResult one = TracePhotons(scene.accel, scene.lights, o);
    EXPECT_TRUE(Same(none.direct, one.direct));
    EXPECT_TRUE(Same(none.indirect, one.indirect));
    EXPECT_TRUE(Same(none.caustic, one.caustic));
    EXPECT_EQ(none.rays, one.rays);
    o.caustic_split = 2;  // and splitting does change the caustic photons
    EXPECT_FALSE(Same(none.caustic, TracePhotons(scene.accel, scene.lights, o).caustic));
  }
  // The job setting: S = 1 keeps the map fingerprint (map caches, checkpoints) and S > 1 changes it.
  JobRenderSettings s;
  s.direct = DirectLightMode::kMonteCarlo;
  const std::string before = s.MapFingerprint();
  s.caustic_split = 1;
  s.caustic_split_method = CausticSplitMethod::kMetropolis;
  EXPECT_EQ(s.MapFingerprint(), before);
  s.caustic_split = 4;
  const std::string metropolis = s.MapFingerprint();
  EXPECT_NE(metropolis, before);
  s.caustic_split_method = CausticSplitMethod::kBrute;
  EXPECT_NE(s.MapFingerprint(), metropolis);
}

// docs/design.md, G1: the same photons for 1, 2 and 3 threads, with either method.
TEST(CausticSplitting, SamePhotonsForAnyThreadCount) {
  const Scene scene;
  for (CausticSplitMethod method : {CausticSplitMethod::kBrute, CausticSplitMethod::kMetropolis}) {
    SCOPED_TRACE(CausticSplitMethodName(method));
    PhotonTracerOptions o = TracerOptions(3 * kPhotonTracingChunk + 100, 21, 5, method);
    o.threads = 1;
    const PhotonTracingResult one = TracePhotons(scene.accel, scene.lights, o);
    for (int threads : {2, 3}) {
      o.threads = threads;
      const PhotonTracingResult many = TracePhotons(scene.accel, scene.lights, o);
      EXPECT_TRUE(Same(one.direct, many.direct)) << threads;
      EXPECT_TRUE(Same(one.indirect, many.indirect)) << threads;
      EXPECT_TRUE(Same(one.caustic, many.caustic)) << threads;
      EXPECT_EQ(one.rays, many.rays);
      // The counts too: one thread takes a path of its own (straight into the result arrays),
      // and the emitted count goes into the map's bytes.
      EXPECT_EQ(one.emitted, many.emitted) << threads;
      EXPECT_EQ(one.rejected, many.rejected) << threads;
      EXPECT_EQ(one.chains, many.chains) << threads;
      EXPECT_EQ(one.mutations, many.mutations) << threads;
      EXPECT_EQ(one.accepted, many.accepted) << threads;
    }
  }
}

std::string Comparable(PhotonMaps maps) {
  maps.stats.trace_seconds = maps.stats.build_seconds = 0;
  maps.stats.stored_power = Rgb(0.0f);
  return SerializePhotonMaps(maps);
}

// Distributed tracing (docs/farm.md, "Photon maps traced once") with splitting: pieces (cut at multiples of
// the tracer's chunk, through their byte form) assemble to the map one process builds.
TEST(CausticSplitting, PiecesAssembleToTheOneProcessMap) {
  const SceneRuntime scene(LoadScene(
      (std::filesystem::path(PF_SOURCE_DIR) / "scenes" / "cornell-sphere/cornell-sphere.json").string()));
  for (CausticSplitMethod method : {CausticSplitMethod::kBrute, CausticSplitMethod::kMetropolis}) {
    SCOPED_TRACE(CausticSplitMethodName(method));
    JobRenderSettings s;
    s.photons = 10001;
    s.caustic_split = 4;
    s.caustic_split_method = method;
    PhotonMapsOptions mo = s.Resolved(scene.description).MapsOptions();
    mo.tracing.map_seed = 99;
    mo.tracing.threads = 2;
    const PhotonMaps whole = PhotonMaps::Build(scene.accel, scene.lights, mo);
    ASSERT_TRUE(whole.caustic);
    EXPECT_GT(whole.caustic->size(), 100u);
    std::vector<PhotonChunk> pieces;
    const std::vector<uint64_t> cuts = {0, 4096, 8192, 10001};
    for (size_t i = 0; i + 1 < cuts.size(); ++i)
      pieces.push_back(DeserializePhotonChunk(
          SerializePhotonChunk(TracePhotonChunk(scene.accel, scene.lights, mo, cuts[i], cuts[i + 1]))));
    const PhotonMaps assembled = AssemblePhotonMaps(pieces, mo);
    EXPECT_EQ(Comparable(DeserializePhotonMaps(SerializePhotonMaps(assembled))),
              Comparable(DeserializePhotonMaps(SerializePhotonMaps(whole))));
    EXPECT_EQ(assembled.stats.emitted, whole.stats.emitted);
    // The chains travel with the pieces: the farm's maps count what a local build counts.
    EXPECT_EQ(assembled.stats.chains, whole.stats.chains);
    EXPECT_EQ(assembled.stats.mutations, whole.stats.mutations);
    EXPECT_EQ(assembled.stats.accepted, whole.stats.accepted);
    if (method == CausticSplitMethod::kMetropolis) {
      EXPECT_GT(whole.stats.mutations, 0u);
    }
  }
}

struct MeanAndError {
  double mean = 0, standard_error = 0;
};
MeanAndError Summarise(const std::vector<double>& v) {
  MeanAndError r;
  for (double x : v) r.mean += x / double(v.size());
  double var = 0;
  for (double x : v) var += (x - r.mean) * (x - r.mean) / double(v.size() - 1);
  r.standard_error = std::sqrt(var / double(v.size()));
  return r;
}

// The image mean over the caustic (the floor under the glass sphere: its shadow and its bright
// focus, lit only through the glass there), 8 maps / 8 path-tracer runs of 256 spp each:
//  * brute force at S = 8 builds the caustic map of 8N photons, and Metropolis one of the same
//    expectation: both agree with no splitting at 8N photons within 4 standard errors of the
//    difference plus 1 % (the global maps differ in density: N against 8N photons);
//  * every photon-map row agrees with the path tracer within 4 standard errors plus 4 % for the
//    photon map's own kernel bias, which depends on the caustic map's density (measured: N
//    photons -0.1 %, 8N photons +3.1 %, brute S = 8 +3.2 %, Metropolis S = 8 +3.6 % ± 0.7 %), and
//    the bound is checked to stay below 10 %, so a caustic map off by 1/S, or Metropolis states
//    stored without their weights, fails.
TEST(CausticSplitting, CausticRegionMeanMatchesThePathTracer) {
  const SceneRuntime runtime(GlassSphereScene());
  CameraSpec spec;
  spec.eye = {0.0f, -2.2f, 2.2f};
  spec.look_at = {0.0f, 0.0f, 0.0f};
  spec.up = {0, 0, 1};
  spec.vfov_degrees = 40.0f;
  spec.width = 40;
  spec.height = 30;
  const Camera camera(spec);
  std::vector<bool> region(size_t(spec.width * spec.height), false);
  size_t pixels = 0;
  for (int y = 0; y < spec.height; ++y)
    for (int x = 0; x < spec.width; ++x) {
      const std::optional<SurfaceHit> hit = runtime.accel.Intersect(camera.GenerateRay(x, y, 0.5f, 0.5f));
      if (hit && std::abs(hit->position.z) < 1e-3f && std::hypot(hit->position.x, hit->position.y) < 0.7f) {
        region[size_t(y * spec.width + x)] = true;
        ++pixels;
      }
    }
  ASSERT_GT(pixels, 100u);
  auto mean_of = [&](const Image& img) {
    double sum = 0;
    for (int y = 0; y < spec.height; ++y)
      for (int x = 0; x < spec.width; ++x)
        if (region[size_t(y * spec.width + x)]) {
          const Rgb& c = img.at(x, y);
          sum += (double(c.r) + c.g + c.b) / 3.0;
        }
    return sum / double(pixels);
  };
  auto render = [&](IntegratorKind kind, uint32_t split, CausticSplitMethod method, uint32_t spp,
                    uint64_t seed, uint64_t photons = 20000) {
    JobRenderSettings s;
    s.integrator = kind;
    s.photons = photons;
    s.k = 50;
    s.direct = DirectLightMode::kMonteCarlo;
    s.caustic_split = split;
    s.caustic_split_method = method;
    const PlanSpec plan{.kind = PlanKind::kMultipleMaps, .maps = 1, .samples_per_pixel = spp};
    return mean_of(RenderPlanLocally(runtime, spec, s, plan, seed, 0));
  };
  constexpr int kRuns = 8;
  std::vector<double> path, none, brute, metropolis, none8;
  for (int i = 0; i < kRuns; ++i) {
    none8.push_back(render(IntegratorKind::kPhotonMap, 1, CausticSplitMethod::kBrute, 4, 2000 + i, 160000));
    path.push_back(render(IntegratorKind::kPath, 1, CausticSplitMethod::kBrute, 256, 1000 + i));
    none.push_back(render(IntegratorKind::kPhotonMap, 1, CausticSplitMethod::kBrute, 4, 2000 + i));
    brute.push_back(render(IntegratorKind::kPhotonMap, 8, CausticSplitMethod::kBrute, 4, 2000 + i));
    metropolis.push_back(render(IntegratorKind::kPhotonMap, 8, CausticSplitMethod::kMetropolis, 4, 2000 + i));
  }
  const MeanAndError pt = Summarise(path), eight = Summarise(none8);
  auto expect_agrees = [](const char* name, const MeanAndError& a, const MeanAndError& b, double bias) {
    const double tol = 4.0 * std::hypot(a.standard_error, b.standard_error) + bias * b.mean;
    std::printf("%s: %.6g ± %.2g against %.6g ± %.2g, tolerance %.3g (%.1f %%)\n", name, a.mean,
                a.standard_error, b.mean, b.standard_error, tol, 100.0 * tol / b.mean);
    EXPECT_NEAR(a.mean, b.mean, tol) << name;
    EXPECT_LT(tol, 0.1 * b.mean) << name;
  };
  expect_agrees("brute S=8 vs no splitting 8N", Summarise(brute), eight, 0.01);
  expect_agrees("metropolis S=8 vs no splitting 8N", Summarise(metropolis), eight, 0.01);
  for (const auto& [name, values] :
       {std::pair{"no splitting N vs path", &none}, std::pair{"brute S=8 vs path", &brute},
        std::pair{"metropolis S=8 vs path", &metropolis}, std::pair{"no splitting 8N vs path", &none8}})
    expect_agrees(name, Summarise(*values), pt, 0.04);
}

}  // namespace
}  // namespace pf
