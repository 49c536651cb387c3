// Photon tracing (Wald 1999, §2.2) and the standalone photon-map estimate (§2.5): power
// bookkeeping, determinism across thread counts, caustic classification, and the furnace.
#include "common/photon/photon_tracer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "common/lights/light_sampler.h"
#include "common/photon/photon_maps.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/sampling/sample_layout.h"
#include "common/sampling/sampler.h"
#include "common/scene/scene_loader.h"
#include "tests/common/test_scenes.h"

namespace pf {
namespace {

using testing::AddMaterial;
using testing::AddQuad;

using testing::FurnaceScene;

// Maps of `photons` emitted photons with map seed `seed`, other options at their defaults.
PhotonMapsOptions Emitting(uint64_t photons, uint64_t seed) {
  PhotonMapsOptions mo;
  mo.tracing.photons = photons;
  mo.tracing.map_seed = seed;
  return mo;
}

// Every emitted unit of power is stored once per diffuse bounce until absorbed: in a closed
// furnace of albedo a the expected stored power is Φ/(1−a). Per-photon std of the stored
// total is ≈0.9·mean (geometric walk length), so with 200k photons the std of the sum is
// 0.2 %: 1 % is a 5σ bound.
TEST(PhotonTracer, FurnaceStoredPowerIsEmittedOverOneMinusAlbedo) {
  const SceneDescription scene = FurnaceScene(0.8f);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  PhotonTracerOptions o;
  o.photons = 200000;
  o.map_seed = 5;
  const PhotonTracingResult r = TracePhotons(accel, lights, o);
  const Rgb emitted = r.emitted_power;
  // Emitted power is exactly Σ π·A·Le of the emitter triangles.
  double area = 0;
  for (uint32_t t = 0; t < scene.NumTriangles(); ++t) area += accel.triangle_area(t);
  EXPECT_NEAR(emitted.r, kPi * area, 1e-4 * kPi * area);
  // First hits are exactly the emitted photons (closed sphere: nothing escapes).
  EXPECT_EQ(r.direct.size(), o.photons);
  const Rgb stored = r.StoredPower();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(stored[c], emitted[c] / 0.2f, 0.01f * emitted[c] / 0.2f) << c;
  EXPECT_TRUE(r.caustic.empty());
}

TEST(PhotonTracer, SameSeedSamePhotonsForOneAndTwoThreads) {
  const SceneDescription scene = FurnaceScene(0.7f);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  PhotonTracerOptions o;
  o.photons = 20000;  // several chunks
  o.map_seed = 77;
  o.threads = 1;
  const PhotonTracingResult one = TracePhotons(accel, lights, o);
  o.threads = 2;
  const PhotonTracingResult two = TracePhotons(accel, lights, o);
  o.threads = 3;
  const PhotonTracingResult three = TracePhotons(accel, lights, o);
  auto same = [](const auto& a, const auto& b) {
    if (a.size() != b.size()) return false;
    return std::memcmp(a.data(), b.data(), a.size() * sizeof(TracedPhoton)) == 0;
  };
  EXPECT_TRUE(same(one.direct, two.direct));
  EXPECT_TRUE(same(one.indirect, two.indirect));
  EXPECT_TRUE(same(one.caustic, two.caustic));
  EXPECT_TRUE(same(one.indirect, three.indirect));
  EXPECT_EQ(one.rays, three.rays);
  o.map_seed = 78;
  const PhotonTracingResult other = TracePhotons(accel, lights, o);
  EXPECT_FALSE(same(one.indirect, other.indirect)) << "another seed must give other photons";
}

// Photon i leaves the light LightSampler::Sample gives for its stratified light choice
// u = (i + ξ)/N and its point numbers (§2.2: photons per emitter ∝ power, a uniform point on it),
// with Φ = Le·π/(pdf_area·N): the tracer's emitter table must give exactly that point and power.
// In the closed furnace (a sphere of 8192 emitting triangles of different areas) every photon's
// first hit stores it, so direct photon i is emitted photon i and its origin is the light point,
// moved off the emitter to its front as the photon's ray left it (TracedPhoton::origin).
// Both paths: the Sobol lanes computed ahead in batches, and the independent sampler.
TEST(PhotonTracer, EmissionIsTheLightSamplersSample) {
  const SceneDescription scene = FurnaceScene(0.5f);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  ASSERT_GT(lights.num_emitting_triangles(), 10u);
  for (SamplerKind kind : {SamplerKind::kSobol, SamplerKind::kIndependent}) {
    PhotonTracerOptions o;
    o.photons = 5000;
    o.map_seed = 21;
    o.sampler = kind;
    o.threads = 1;
    const PhotonTracingResult r = TracePhotons(accel, lights, o);
    ASSERT_EQ(r.direct.size(), o.photons);
    size_t emitters_seen = 0;
    std::vector<bool> seen(accel.description().NumTriangles(), false);
    for (uint64_t i = 0; i < o.photons; ++i) {
      Sampler sampler = Sampler::ForPhoton(kind, o.map_seed, i);
      const double jitter = kind == SamplerKind::kSobol ? double(sampler.Get1D(kPhotonLightSlot))
                                                        : sampler.rng().UniformDouble();
      const float u = std::min(float((double(i) + jitter) / double(o.photons)), 0x1.fffffep-1f);
      const Sample2 point = sampler.Get2D(kPhotonPointSlot);
      const LightSample ls = lights.Sample(u, point.u, point.v);
      const Rgb power = ls.radiance * (kPi / (ls.pdf_area * float(o.photons)));
      const TracedPhoton& p = r.direct[i];
      const Vec3 origin = OffsetRayOrigin(ls.position, ls.normal, accel.epsilon());
      ASSERT_EQ(std::memcmp(&p.origin, &origin, sizeof(Vec3)), 0) << i;
      ASSERT_EQ(std::memcmp(&p.power, &power, sizeof(Rgb)), 0) << i;
      ASSERT_EQ(p.light, ls.light) << i;
      if (!seen[ls.triangle]) {
        seen[ls.triangle] = true;
        ++emitters_seen;
      }
    }
    EXPECT_GT(emitters_seen, 4000u);  // photons left from thousands of the 8192 emitters
  }
}

// The plain walk (TracePlainWalk: IntersectWalk, WalkRoulette, Sobol lanes and light choice
// computed ahead in batches) must store exactly the photons of the general walk that Metropolis
// caustic splitting takes (TraceEmitted: Intersect, a Bsdf at every hit, lanes computed per
// photon; the emission both share is checked above): Metropolis splitting changes only the caustic stores, so
// the direct and indirect arrays of both are the same walks. Shipped scenes with flat diffuse
// walls (cornell-box), smooth vertex normals and a mirror and a glass sphere (cornell-sphere) and
// several lights (office3); both sampler kinds; the bounce cap; one and two threads.
TEST(PhotonTracer, PlainWalkStoresTheGeneralWalksPhotons) {
  const auto same = [](const TracedPhotons& a, const TracedPhotons& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(TracedPhoton)) == 0;
  };
  for (const char* rel :
       {"cornell-box/cornell-box.json", "cornell-sphere/cornell-sphere.json", "office3/office3.json"}) {
    const SceneDescription scene = LoadScene(std::string(PF_SOURCE_DIR) + "/scenes/" + rel);
    const EmbreeScene accel(scene);
    const LightSampler lights(accel);
    for (int variant = 0; variant < 4; ++variant) {
      PhotonTracerOptions o;
      o.photons = 6000;  // two chunks, the second ending inside a batch of 16
      o.map_seed = 9 + uint64_t(variant);
      o.sampler = variant == 1 ? SamplerKind::kIndependent : SamplerKind::kSobol;
      if (variant == 2) o.max_bounces = 2;
      o.threads = variant == 3 ? 2 : 1;
      const PhotonTracingResult plain = TracePhotons(accel, lights, o);
      o.caustic_split = 2;
      o.caustic_split_method = CausticSplitMethod::kMetropolis;
      const PhotonTracingResult general = TracePhotons(accel, lights, o);
      EXPECT_GT(plain.direct.size(), 1000u) << rel;
      EXPECT_TRUE(same(plain.direct, general.direct)) << rel << " variant " << variant;
      EXPECT_TRUE(same(plain.indirect, general.indirect)) << rel << " variant " << variant;
    }
  }
}

// The whole map build — tracing, the parallel compaction to 18 bytes, the parallel
// left-balanced kd-tree build and the attributes that follow it — gives the same maps for
// any thread count (the furnace stores ~3 photons per emitted one: 150k photons, enough for
// the parallel kd-tree build to split).
TEST(PhotonMaps, SameMapsAndAttributesForAnyThreadCount) {
  const SceneDescription scene = FurnaceScene(0.7f);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  PhotonMapsOptions mo = Emitting(50000, 5);
  mo.separate_direct = true;
  mo.keep_light_ids = true;
  mo.keep_origins = true;
  mo.tracing.threads = 1;
  const PhotonMaps one = PhotonMaps::Build(accel, lights, mo);
  ASSERT_GT(one.global->size(), 2u * 32768u);
  for (int threads : {2, 3}) {
    mo.tracing.threads = threads;
    const PhotonMaps many = PhotonMaps::Build(accel, lights, mo);
    for (const auto& [a, b] :
         {std::pair{one.global.get(), many.global.get()}, std::pair{one.direct.get(), many.direct.get()}}) {
      ASSERT_EQ(a->size(), b->size());
      EXPECT_EQ(std::memcmp(a->photons().data(), b->photons().data(), a->size() * sizeof(Photon)), 0)
          << threads << " threads";
    }
    EXPECT_EQ(one.global_attributes.light, many.global_attributes.light);
    ASSERT_EQ(one.global_attributes.origin.size(), many.global_attributes.origin.size());
    for (size_t i = 0; i < one.global_attributes.origin.size(); ++i)
      ASSERT_EQ(one.global_attributes.origin[i], many.global_attributes.origin[i]) << i;
  }
}

// A mirror between a light and a floor: photons reflected by it land as caustic photons; the
// ones arriving straight from the light are direct. With no singular surface there is none.
TEST(PhotonTracer, CausticClassificationFollowsTheThesisDefinition) {
  SceneDescription s;
  const Material floor{.diffuse_reflectance = Rgb(0.5f)};
  const Material mirror{.specular_reflectance = Rgb(1.0f)};
  const Material light{.emission = Rgb(10.0f)};
  const uint32_t floor_id = AddMaterial(s, floor);
  const uint32_t mirror_id = AddMaterial(s, mirror);
  const uint32_t light_id = AddMaterial(s, light);
  AddQuad(s, {-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}, floor_id);
  // Light facing down at z = 2, mirror facing up at z = 3 above it (light on both sides? no:
  // a second light quad facing up so that photons reach the mirror).
  AddQuad(s, {-0.5f, -0.5f, 2}, {-0.5f, 0.5f, 2}, {0.5f, 0.5f, 2}, {0.5f, -0.5f, 2}, light_id, 0);
  AddQuad(s, {-0.5f, -0.5f, 2.001f}, {0.5f, -0.5f, 2.001f}, {0.5f, 0.5f, 2.001f}, {-0.5f, 0.5f, 2.001f},
          light_id, 1);
  AddQuad(s, {-3, -3, 3}, {-3, 3, 3}, {3, 3, 3}, {3, -3, 3}, mirror_id);  // faces down
  s.num_lights = 2;
  const EmbreeScene accel(s);
  const LightSampler lights(accel);
  ASSERT_TRUE(SceneNeedsCausticMap(s));
  PhotonTracerOptions o;
  o.photons = 50000;
  const PhotonTracingResult r = TracePhotons(accel, lights, o);
  EXPECT_GT(r.caustic.size(), 1000u);
  EXPECT_GT(r.direct.size(), 1000u);
  for (const TracedPhoton& p : r.caustic) ASSERT_LT(p.position.z, 1e-3f) << "caustics land on the floor";
  // Caustic photons come from the mirror: their origin is on it.
  for (const TracedPhoton& p : r.caustic) ASSERT_NEAR(p.origin.z, 3.0f, 1e-3f);
  for (const TracedPhoton& p : r.direct) ASSERT_NEAR(p.origin.z, 2.0f, 0.01f);

  SceneDescription diffuse_only = s;
  diffuse_only.materials[mirror_id] = floor;
  EXPECT_FALSE(SceneNeedsCausticMap(diffuse_only));
}

// In the furnace the direct visualisation of the estimate equals Le/(1−a) within 2 %
// (N = 1M photons, k = 100). One estimate from k photons has a relative std of ~1/√k = 10 %
// and neighbouring estimates share photons (the low-frequency noise of §3.3). A pixel of this
// 4×4, 90° camera covers ~0.5 m of wall, ~700 disjoint search disks of r ≈ 9 mm, so its
// 1024 jittered estimates average to ~0.4 %: 2 % is a 5σ bound. The thesis's variant that
// also counts the k-th photon is high by k/(k−1) ≈ 1 %, which this bound would hide, so it is
// checked on the image mean instead.
TEST(PhotonMapIntegrator, FurnaceEstimateWithinTwoPercent) {
  const SceneDescription scene = FurnaceScene(0.8f);
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  const PhotonMapsOptions mo = Emitting(1000000, 3);
  const PhotonMaps maps = PhotonMaps::Build(accel, lights, mo);
  EXPECT_EQ(maps.caustic, nullptr) << "diffuse-only scene: no caustic map";
  // The 18-byte photons (RGBE power) still hold the right total power.
  double stored = 0;
  for (const Photon& p : maps.global->photons()) stored += p.Power().r;
  EXPECT_NEAR(stored, maps.stats.emitted_power.r / 0.2, 0.01 * maps.stats.emitted_power.r / 0.2);

  PhotonMapIntegratorOptions io;
  io.global.k = 100;
  const PhotonMapIntegrator integrator(accel, maps, io);
  const CameraSpec cam = testing::FurnaceCamera();
  const Image img = RenderImage(integrator, Camera(cam), RenderOptions{.spp = 1024, .seed = 1});
  double mean = 0;
  for (size_t i = 0; i < img.size(); ++i) {
    mean += img[i].Mean() / double(img.size());
    for (int c = 0; c < 3; ++c) ASSERT_NEAR(img[i][c], 5.0f, 0.1f) << "pixel " << i << " channel " << c;
  }
  // Image mean (~0.1 % std): unbiased within 0.5 %; the thesis's Σ over all k is k/(k−1) high
  // on the reflected part (4 of the 5): +0.8 %.
  EXPECT_NEAR(mean, 5.0, 0.025);
  io.global.exclude_boundary_photon = false;
  const PhotonMapIntegrator thesis(accel, maps, io);
  const Image img2 = RenderImage(thesis, Camera(cam), RenderOptions{.spp = 1024, .seed = 1});
  double mean2 = 0;
  for (size_t i = 0; i < img2.size(); ++i) mean2 += img2[i].Mean() / double(img2.size());
  EXPECT_NEAR(mean2 - mean, 4.0 / 99.0, 0.01) << "counting the k-th photon adds 4·1/(k−1)";
}

}  // namespace
}  // namespace pf
