// proto/convert.h: every message survives core -> proto -> core unchanged, and every invalid
// field is refused with an InputError whose message starts with the field's path (LimitError,
// i.e. RESOURCE_EXHAUSTED at the RPC edge, for well-formed values over a limit).

#include "proto/convert.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

namespace pf {
namespace {
namespace v1 = photonfarm::v1;
using ::testing::HasSubstr;
using ::testing::StartsWith;

v1::Camera GoodCamera() {
  v1::Camera c;
  c.mutable_eye()->set_z(5);
  c.mutable_up()->set_y(1);
  c.set_vfov_degrees(40);
  c.set_width(64);
  c.set_height(48);
  return c;
}

v1::RenderSettings GoodSettings() {
  v1::RenderSettings s;
  s.set_integrator(v1::INTEGRATOR_PHOTONMAP);
  s.mutable_photon_map()->set_photons(1000);
  s.mutable_photon_map()->set_k(50);
  return s;
}

// Runs `f` and returns the InputError's message (fails the test if nothing is thrown).
template <typename Error = InputError>
std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
    return "";
  }
  ADD_FAILURE() << "accepted";
  return "";
}

TEST(Convert, CameraRoundTrips) {
  v1::Camera c = GoodCamera();
  c.mutable_eye()->set_x(1.5);
  c.mutable_look_at()->set_y(-2.25);
  const CameraSpec cam = CameraFromProto(c, "spec.camera");
  EXPECT_EQ(cam.eye, Vec3(1.5f, 0, 5));
  EXPECT_EQ(cam.look_at, Vec3(0, -2.25f, 0));
  EXPECT_EQ(cam.width, 64);
  EXPECT_EQ(cam.height, 48);
  v1::Camera back;
  CameraToProto(cam, &back);
  EXPECT_EQ(back.SerializeAsString(), c.SerializeAsString());
}

TEST(Convert, BadCamerasNameTheirField) {
  auto with = [](auto edit) {
    v1::Camera c = GoodCamera();
    edit(c);
    return ErrorOf([&] { CameraFromProto(c, "spec.camera"); });
  };
  EXPECT_THAT(with([](v1::Camera& c) { c.mutable_eye()->set_x(std::nan("")); }),
              StartsWith("spec.camera.eye:"));
  EXPECT_THAT(with([](v1::Camera& c) { c.mutable_up()->set_z(INFINITY); }), StartsWith("spec.camera.up:"));
  EXPECT_THAT(with([](v1::Camera& c) { c.set_vfov_degrees(0); }), StartsWith("spec.camera.vfov_degrees:"));
  EXPECT_THAT(with([](v1::Camera& c) { c.set_vfov_degrees(180); }), StartsWith("spec.camera.vfov_degrees:"));
  EXPECT_THAT(with([](v1::Camera& c) { c.set_width(0); }), StartsWith("spec.camera.width/height:"));
  EXPECT_THAT(with([](v1::Camera& c) { c.mutable_look_at()->set_z(5); }), StartsWith("spec.camera.look_at:"));
  EXPECT_THAT(with([](v1::Camera& c) { c.mutable_up()->set_y(0), c.mutable_up()->set_z(1); }),
              StartsWith("spec.camera.up:"));
  v1::Camera big = GoodCamera();
  big.set_width(kMaxImageSide + 1);
  EXPECT_THAT(ErrorOf<LimitError>([&] { CameraFromProto(big, "spec.camera"); }),
              HasSubstr("exceeds the limit"));
  big.set_width(kMaxImageSide);
  big.set_height(kMaxImageSide);  // each side in range, the product over the pixel limit
  EXPECT_THAT(ErrorOf<LimitError>([&] { CameraFromProto(big, "spec.camera"); }),
              HasSubstr("exceeds the limit"));
}

TEST(Convert, EverySettingRoundTrips) {
  v1::RenderSettings s = GoodSettings();
  v1::PhotonMapSettings& pm = *s.mutable_photon_map();
  pm.set_structure(v1::MAP_STRUCTURE_GRID);
  pm.set_caustic(v1::CAUSTIC_MODE_OFF);
  pm.set_caustic_radius(0.25);
  pm.set_glossy_depth(3);
  pm.set_direction_test(v1::DIRECTION_TEST_AFTER_QUERY);
  pm.set_direct(v1::DIRECT_LIGHT_PHOTON_DIRECT);
  pm.set_shadow_rays(7);
  pm.set_light_uniform_fraction(0.5);
  pm.set_photon_direct_k(9);
  pm.set_non_contributing(v1::NON_CONTRIBUTING_EACH);
  pm.set_photon_direct_cache(0.125);
  pm.set_local_pass_rays(4);
  pm.set_occlusion_test(true);
  pm.set_adaptive_k_min(10);
  pm.set_kd_split(v1::KD_SPLIT_CYCLE);
  pm.set_local_pass_lookup(v1::LOCAL_PASS_LOOKUP_PRECOMPUTED);
  pm.set_irradiance_cache_error(0.25);
  pm.set_importance(v1::IMPORTANCE_MODE_AUTO);
  pm.set_importance_min_probability(0.125);
  pm.set_importance_strength(2.5);
  pm.set_importons(5000);
  s.set_sampler(v1::SAMPLER_INDEPENDENT);
  const JobRenderSettings core = SettingsFromProto(s, "spec.settings");
  EXPECT_EQ(core.structure, PhotonMapKind::kGrid);
  EXPECT_EQ(core.caustic, CausticMapMode::kOff);
  EXPECT_EQ(core.direct, DirectLightMode::kPhotonDirect);
  EXPECT_EQ(core.non_contributing, NonContributingMode::kEachOne);
  EXPECT_EQ(core.kd_split, KdSplitRule::kLevelCycle);
  EXPECT_EQ(core.local_pass_rays, 4);
  EXPECT_EQ(core.irradiance_cache_error, 0.25f);
  EXPECT_TRUE(core.occlusion_test);
  EXPECT_TRUE(core.site_occlusion_test);  // OFF contradicts occlusion_test: its own test below
  EXPECT_EQ(core.importance, ImportanceMode::kAuto);
  EXPECT_EQ(core.importance_min_probability, 0.125f);
  EXPECT_EQ(core.importance_strength, 2.5f);
  EXPECT_EQ(core.importons, 5000u);
  v1::RenderSettings back;
  SettingsToProto(core, &back);
  EXPECT_EQ(SettingsFromProto(back, "x").MapFingerprint(), core.MapFingerprint());
  EXPECT_EQ(back.SerializeAsString(), s.SerializeAsString());

  v1::RenderSettings path;
  path.set_integrator(v1::INTEGRATOR_PATH);
  EXPECT_EQ(SettingsFromProto(path, "s").integrator, IntegratorKind::kPath);
}

TEST(Convert, SiteOcclusionTestOffRoundTrips) {
  v1::RenderSettings s = GoodSettings();
  v1::PhotonMapSettings& pm = *s.mutable_photon_map();
  pm.set_local_pass_rays(8);
  pm.set_local_pass_lookup(v1::LOCAL_PASS_LOOKUP_PRECOMPUTED);
  pm.set_site_occlusion_test(v1::SITE_OCCLUSION_TEST_OFF);
  const JobRenderSettings core = SettingsFromProto(s, "spec.settings");
  EXPECT_FALSE(core.site_occlusion_test);
  v1::RenderSettings back;
  SettingsToProto(core, &back);
  EXPECT_EQ(back.photon_map().site_occlusion_test(), v1::SITE_OCCLUSION_TEST_OFF);
  EXPECT_FALSE(SettingsFromProto(back, "x").site_occlusion_test);
  // ON is the default and is written as such (unset): older readers see the same setting.
  pm.clear_site_occlusion_test();
  v1::RenderSettings on;
  SettingsToProto(SettingsFromProto(s, "spec.settings"), &on);
  EXPECT_EQ(on.photon_map().site_occlusion_test(), v1::SITE_OCCLUSION_TEST_UNSPECIFIED);
}

TEST(Convert, BadSettingsNameTheirField) {
  auto with = [](auto edit) {
    v1::RenderSettings s = GoodSettings();
    edit(*s.mutable_photon_map());
    return ErrorOf([&] { SettingsFromProto(s, "spec.settings"); });
  };
  const std::string f = "spec.settings.photon_map.";
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_photons(0); }), StartsWith(f + "photons:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_k(0); }), StartsWith(f + "k:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_caustic_radius(-1); }),
              StartsWith(f + "caustic_radius:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_caustic_radius(INFINITY); }),
              StartsWith(f + "caustic_radius:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_glossy_depth(65); }),
              StartsWith(f + "glossy_depth:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_shadow_rays(0); }), StartsWith(f + "shadow_rays:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_light_uniform_fraction(1.5); }),
              StartsWith(f + "light_uniform_fraction:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_photon_direct_cache(-0.1); }),
              StartsWith(f + "photon_direct_cache:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_local_pass_rays(kMaxShadowRays + 1); }),
              StartsWith(f + "local_pass_rays:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_irradiance_cache_error(-0.1); }),
              StartsWith(f + "irradiance_cache_error:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_irradiance_cache_error(NAN); }),
              StartsWith(f + "irradiance_cache_error:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_local_pass_rays(0);
                p.set_irradiance_cache_error(0.2);
              }),
              StartsWith(f + "irradiance_cache_error: caches the local pass's gathers"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_local_pass_lookup(v1::LOCAL_PASS_LOOKUP_FULL);
                p.set_site_occlusion_test(v1::SITE_OCCLUSION_TEST_OFF);
              }),
              StartsWith(f + "site_occlusion_test: OFF applies to the precomputed sites only"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_site_occlusion_test(static_cast<v1::SiteOcclusionTest>(7));
              }),
              StartsWith(f + "site_occlusion_test: unknown value"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_local_pass_lookup(v1::LOCAL_PASS_LOOKUP_PRECOMPUTED);
                p.set_local_pass_rays(0);
                p.set_irradiance_cache_error(0.0);
                p.set_site_occlusion_test(v1::SITE_OCCLUSION_TEST_OFF);
              }),
              StartsWith(f + "site_occlusion_test: OFF applies to the local pass's precomputed sites"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_local_pass_lookup(v1::LOCAL_PASS_LOOKUP_PRECOMPUTED);
                p.set_local_pass_rays(8);
                p.set_occlusion_test(true);
                p.set_site_occlusion_test(v1::SITE_OCCLUSION_TEST_OFF);
              }),
              StartsWith(f + "site_occlusion_test: OFF contradicts " + f + "occlusion_test = true"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_adaptive_k_min(51); }),
              StartsWith(f + "adaptive_k_min:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_direct(static_cast<v1::DirectLight>(99)); }),
              StartsWith(f + "direct:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_importance(static_cast<v1::ImportanceMode>(9)); }),
              StartsWith(f + "importance:"));
  // Distributed tracing builds maps without the camera's importons (§4.7).
  for (v1::ImportanceMode mode : {v1::IMPORTANCE_MODE_ON, v1::IMPORTANCE_MODE_AUTO})
    EXPECT_THAT(with([&](v1::PhotonMapSettings& p) {
                  p.set_importance(mode);
                  p.set_map_tracing(v1::MAP_TRACING_DISTRIBUTED);
                }),
                StartsWith(f + "map_tracing: distributed tracing does not build importance-driven maps"));
  for (double bad : {0.0, -0.5, 1.5, double(NAN)})
    EXPECT_THAT(with([&](v1::PhotonMapSettings& p) { p.set_importance_min_probability(bad); }),
                StartsWith(f + "importance_min_probability:"));
  for (double bad : {0.0, -1.0, 2e6, double(INFINITY), double(NAN)})
    EXPECT_THAT(with([&](v1::PhotonMapSettings& p) { p.set_importance_strength(bad); }),
                StartsWith(f + "importance_strength:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_importons(kMaxImportons + 1); }),
              StartsWith(f + "importons:"));
  v1::RenderSettings none;
  EXPECT_THAT(ErrorOf([&] { SettingsFromProto(none, "spec.settings"); }),
              StartsWith("spec.settings.integrator:"));
  v1::RenderSettings many = GoodSettings();
  many.mutable_photon_map()->set_photons(kMaxPhotonsPerMap + 1);
  EXPECT_THAT(ErrorOf<LimitError>([&] { SettingsFromProto(many, "spec.settings"); }),
              StartsWith(f + "photons:"));
  many.mutable_photon_map()->set_photons(1);
  many.mutable_photon_map()->set_k(kMaxK + 1);
  EXPECT_THAT(ErrorOf<LimitError>([&] { SettingsFromProto(many, "spec.settings"); }), StartsWith(f + "k:"));
}

TEST(Convert, PlansRoundTripAndNameTheirField) {
  for (const PlanKind kind :
       {PlanKind::kMultipleMaps, PlanKind::kMapsInTurn, PlanKind::kSkipping, PlanKind::kProgressive}) {
    PlanSpec p;
    p.kind = kind;
    p.maps = 3;
    p.samples_per_pixel = 5;
    p.tile_size = 16;
    if (kind == PlanKind::kMultipleMaps) p.tail_tile_size = 16;  // carried, checked by ValidatePlan
    p.stride = 4;
    p.rounds = 2;
    v1::Plan proto;
    PlanToProto(p, &proto);
    const PlanSpec back = PlanFromProto(proto, "spec.plan");
    EXPECT_EQ(back.kind, kind);
    EXPECT_EQ(back.samples_per_pixel, 5u);
    EXPECT_EQ(back.tail_tile_size, p.tail_tile_size);
    if (kind == PlanKind::kProgressive) {
      EXPECT_EQ(back.maps, 3u);  // the passes
    }
    v1::Plan again;
    PlanToProto(back, &again);
    EXPECT_EQ(again.SerializeAsString(), proto.SerializeAsString());
  }
  v1::Plan empty;
  EXPECT_THAT(ErrorOf([&] { PlanFromProto(empty, "spec.plan"); }), StartsWith("spec.plan:"));
  v1::Plan skip;
  skip.mutable_skipping()->set_stride(0);
  skip.mutable_skipping()->set_rounds(1);
  skip.mutable_skipping()->set_samples_per_pixel(1);
  EXPECT_THAT(ErrorOf([&] { PlanFromProto(skip, "spec.plan"); }), StartsWith("spec.plan.skipping.stride:"));
  v1::Plan spp;
  spp.mutable_multiple_maps()->set_maps(1);
  spp.mutable_multiple_maps()->set_samples_per_pixel(kMaxSamplesPerPixel + 1);
  EXPECT_THAT(ErrorOf<LimitError>([&] { PlanFromProto(spp, "spec.plan"); }),
              StartsWith("spec.plan.multiple_maps.samples_per_pixel:"));
  v1::Plan passes;
  passes.mutable_progressive()->set_samples_per_pixel(1);
  EXPECT_THAT(ErrorOf([&] { PlanFromProto(passes, "spec.plan"); }),
              StartsWith("spec.plan.progressive.passes:"));
}

TEST(Convert, TasksRoundTripAndRefuseEmptySampleRanges) {
  TaskSpec t;
  t.task_id = 17;
  t.map_index = 3;
  t.map_seed = 0xfeedface12345678ull;
  t.pixel_seed = 99;
  t.pixels.kind = PixelSubset::Kind::kPermutationStride;
  t.pixels.permutation_seed = 7;
  t.pixels.offset = 2;
  t.pixels.stride = 5;
  t.sample_begin = 4;
  t.sample_end = 8;
  v1::Task proto;
  TaskSpecToProto(t, &proto);
  const TaskSpec back = TaskSpecFromProto(proto);
  EXPECT_EQ(back.task_id, 17u);
  EXPECT_EQ(back.map_seed, t.map_seed);
  EXPECT_EQ(back.pixels.kind, PixelSubset::Kind::kPermutationStride);
  EXPECT_EQ(back.pixels.offset, 2u);
  EXPECT_EQ(back.sample_end, 8u);
  EXPECT_FALSE(back.progressive);
  v1::Task again;
  TaskSpecToProto(back, &again);
  EXPECT_EQ(again.SerializeAsString(), proto.SerializeAsString());
  t.progressive = true;  // a progressive plan's pass
  v1::Task pass;
  TaskSpecToProto(t, &pass);
  EXPECT_TRUE(TaskSpecFromProto(pass).progressive);

  proto.set_sample_end(4);
  EXPECT_THAT(ErrorOf([&] { TaskSpecFromProto(proto); }), StartsWith("task.sample_end:"));
  proto.set_sample_end(8);
  proto.clear_pixels();
  EXPECT_THAT(ErrorOf([&] { TaskSpecFromProto(proto); }), StartsWith("task.pixels:"));
}

// The hierarchical plan's part (hierarchical.h, "Parts") and a task's radiance part round-trip;
// part all serialises as before the setting existed; bad values name their field.
TEST(Convert, HierarchyPartAndTaskPartRoundTrip) {
  PlanSpec p;
  p.kind = PlanKind::kHierarchical;
  p.levels = 3;
  p.dims = 2;
  p.base_samples = 16;
  p.min_samples = 1;
  v1::Plan all;
  PlanToProto(p, &all);
  EXPECT_EQ(all.hierarchical().part(), v1::HIERARCHY_PART_ALL);
  EXPECT_EQ(all.hierarchical().direct_samples_per_pixel(), 0u);
  EXPECT_EQ(PlanFromProto(all, "spec.plan").hierarchy_part, HierarchyPart::kAll);
  p.hierarchy_part = HierarchyPart::kIndirect;
  p.direct_samples = 3;
  v1::Plan split;
  PlanToProto(p, &split);
  const PlanSpec back = PlanFromProto(split, "spec.plan");
  EXPECT_EQ(back.hierarchy_part, HierarchyPart::kIndirect);
  EXPECT_EQ(back.direct_samples, 3u);
  v1::Plan again;
  PlanToProto(back, &again);
  EXPECT_EQ(again.SerializeAsString(), split.SerializeAsString());
  split.mutable_hierarchical()->set_part(static_cast<v1::HierarchyPart>(7));
  EXPECT_THAT(ErrorOf([&] { PlanFromProto(split, "spec.plan"); }),
              StartsWith("spec.plan.hierarchical.part:"));
  split.mutable_hierarchical()->set_part(v1::HIERARCHY_PART_INDIRECT);
  split.mutable_hierarchical()->set_direct_samples_per_pixel(kMaxSamplesPerPixel + 1);
  EXPECT_THAT(ErrorOf<LimitError>([&] { PlanFromProto(split, "spec.plan"); }),
              StartsWith("spec.plan.hierarchical.direct_samples_per_pixel:"));

  for (const RadiancePart part : {RadiancePart::kAll, RadiancePart::kMapped, RadiancePart::kUnmapped}) {
    TaskSpec t;
    t.pixels.kind = PixelSubset::Kind::kTile;
    t.pixels.x1 = t.pixels.y1 = 4;
    t.part = part;
    v1::Task proto;
    TaskSpecToProto(t, &proto);
    EXPECT_EQ(TaskSpecFromProto(proto).part, part);
  }
  v1::Task bad;
  TaskSpec t;
  t.pixels.kind = PixelSubset::Kind::kTile;
  t.pixels.x1 = t.pixels.y1 = 4;
  TaskSpecToProto(t, &bad);
  bad.set_part(static_cast<v1::RadiancePart>(9));
  EXPECT_THAT(ErrorOf([&] { TaskSpecFromProto(bad); }), StartsWith("task.part:"));
}

}  // namespace
}  // namespace pf

namespace pf {
namespace {

// Caustic splitting (Wald 1999, §4.6): both methods round-trip, S = 1 (or unset) is
// off and serialises as before the setting existed, bad values name their field.
TEST(Convert, CausticSplitRoundTripsAndIsValidated) {
  for (v1::CausticSplitMethod method :
       {v1::CAUSTIC_SPLIT_METHOD_BRUTE, v1::CAUSTIC_SPLIT_METHOD_METROPOLIS}) {
    v1::RenderSettings s = GoodSettings();
    s.mutable_photon_map()->set_caustic_split(12);
    s.mutable_photon_map()->set_caustic_split_method(method);
    s.mutable_photon_map()->set_direct(v1::DIRECT_LIGHT_MONTE_CARLO);  // the fingerprint needs it resolved
    const JobRenderSettings core = SettingsFromProto(s, "spec.settings");
    EXPECT_EQ(core.caustic_split, 12u);
    EXPECT_EQ(core.caustic_split_method, method == v1::CAUSTIC_SPLIT_METHOD_METROPOLIS
                                             ? CausticSplitMethod::kMetropolis
                                             : CausticSplitMethod::kBrute);
    v1::RenderSettings back;
    SettingsToProto(core, &back);
    EXPECT_EQ(back.photon_map().caustic_split(), 12u);
    // The default (brute) is written unset, as every default that reads back as itself.
    EXPECT_EQ(back.photon_map().caustic_split_method(),
              method == v1::CAUSTIC_SPLIT_METHOD_BRUTE ? v1::CAUSTIC_SPLIT_METHOD_UNSPECIFIED : method);
    EXPECT_EQ(SettingsFromProto(back, "x").MapFingerprint(), core.MapFingerprint());
  }
  for (uint32_t off : {0u, 1u}) {
    v1::RenderSettings s = GoodSettings();
    s.mutable_photon_map()->set_caustic_split(off);
    const JobRenderSettings core = SettingsFromProto(s, "spec.settings");
    EXPECT_EQ(core.caustic_split, 1u);
    v1::RenderSettings back;
    SettingsToProto(core, &back);
    EXPECT_EQ(back.photon_map().caustic_split(), 0u);
    EXPECT_EQ(back.photon_map().caustic_split_method(), v1::CAUSTIC_SPLIT_METHOD_UNSPECIFIED);
  }
  auto with = [](auto edit) {
    v1::RenderSettings s = GoodSettings();
    edit(*s.mutable_photon_map());
    return ErrorOf([&] { SettingsFromProto(s, "spec.settings"); });
  };
  const std::string f = "spec.settings.photon_map.";
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) { p.set_caustic_split(kMaxCausticSplit + 1); }),
              StartsWith(f + "caustic_split:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_caustic_split(4);
                p.set_caustic_split_method(static_cast<v1::CausticSplitMethod>(7));
              }),
              StartsWith(f + "caustic_split_method:"));
  EXPECT_THAT(with([](v1::PhotonMapSettings& p) {
                p.set_caustic_split(4);
                p.set_caustic_split_method(v1::CAUSTIC_SPLIT_METHOD_METROPOLIS);
                p.set_importance(v1::IMPORTANCE_MODE_ON);
              }),
              StartsWith(f + "caustic_split_method: Metropolis splitting is not combined with importance"));
  v1::RenderSettings many = GoodSettings();
  many.mutable_photon_map()->set_photons(kMaxPhotonsPerMap / 8 + 1);
  many.mutable_photon_map()->set_caustic_split(8);
  EXPECT_THAT(ErrorOf<LimitError>([&] { SettingsFromProto(many, "spec.settings"); }),
              StartsWith(f + "caustic_split:"));
  many.mutable_photon_map()->set_caustic_split_method(v1::CAUSTIC_SPLIT_METHOD_METROPOLIS);  // emits N only
  EXPECT_NO_THROW(SettingsFromProto(many, "spec.settings"));
}

}  // namespace
}  // namespace pf
