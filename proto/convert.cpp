#include "proto/convert.h"

#include <cmath>

#include "common/core/error.h"
#include "common/plan/plan_choice.h"
#include "proto/limits.h"

namespace pf {
namespace v1 = photonfarm::v1;

namespace {

Vec3 VecFromProto(const v1::Vec3& v, const std::string& field) {
  const Vec3 out(float(v.x()), float(v.y()), float(v.z()));
  if (!IsFinite(out)) throw InputError(field + ": must be three finite numbers");
  return out;
}
// A camera point: world coordinates, kept in double (the wire's type; common/scene/scene_frame.h),
// checked as the worker will use it: finite as a float.
Vec3d PointFromProto(const v1::Vec3& v, const std::string& field) {
  const Vec3d out(v.x(), v.y(), v.z());
  if (!IsFinite(Vec3(out))) throw InputError(field + ": must be three finite numbers");
  return out;
}
void VecToProto(const Vec3d& v, v1::Vec3* out) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

void RequireAtLeastOne(uint64_t v, const std::string& field) {
  if (v < 1) throw InputError(field + ": must be >= 1");
}

}  // namespace

const char* JobStateName(v1::JobState s) {
  switch (s) {
    case v1::JOB_STATE_QUEUED:
      return "queued";
    case v1::JOB_STATE_RUNNING:
      return "running";
    case v1::JOB_STATE_SUCCEEDED:
      return "succeeded";
    case v1::JOB_STATE_FAILED:
      return "failed";
    case v1::JOB_STATE_CANCELLED:
      return "cancelled";
    default:
      return "unknown";
  }
}

CameraSpec CameraFromProto(const v1::Camera& c, const std::string& field) {
  CameraSpec cam;
  cam.eye = PointFromProto(c.eye(), field + ".eye");
  cam.look_at = PointFromProto(c.look_at(), field + ".look_at");
  cam.up = VecFromProto(c.up(), field + ".up");
  // Checked as the worker will use it: as a float (1e-300 becomes 0, 179.9999999 becomes 180).
  cam.vfov_degrees = float(c.vfov_degrees());
  if (!(cam.vfov_degrees >= kMinVfovDegrees && cam.vfov_degrees <= kMaxVfovDegrees))
    throw InputError(field + ".vfov_degrees: must be in [" + std::to_string(kMinVfovDegrees) + ", " +
                     std::to_string(kMaxVfovDegrees) + "] (as a 32-bit float)");
  if (c.width() == 0 || c.height() == 0) throw InputError(field + ".width/height: must be > 0");
  if (c.width() > kMaxImageSide || c.height() > kMaxImageSide ||
      uint64_t(c.width()) * c.height() > kMaxImagePixels)
    throw LimitError(field + ".width/height: " + std::to_string(c.width()) + "x" +
                     std::to_string(c.height()) + " exceeds the limit (" + std::to_string(kMaxImageSide) +
                     " per side, " + std::to_string(kMaxImagePixels) + " pixels)");
  cam.width = int(c.width());
  cam.height = int(c.height());
  const Vec3 forward(cam.look_at - cam.eye);
  if (!(LengthSquared(forward) > 0.0f)) throw InputError(field + ".look_at: must differ from eye");
  if (!(LengthSquared(Cross(forward, cam.up)) > 0.0f))
    throw InputError(field + ".up: must not be parallel to the view direction");
  return cam;
}

void CameraToProto(const CameraSpec& c, v1::Camera* out) {
  VecToProto(c.eye, out->mutable_eye());
  VecToProto(c.look_at, out->mutable_look_at());
  VecToProto(c.up, out->mutable_up());
  out->set_vfov_degrees(c.vfov_degrees);
  out->set_width(uint32_t(c.width));
  out->set_height(uint32_t(c.height));
}

JobRenderSettings SettingsFromProto(const v1::RenderSettings& s, const std::string& field) {
  JobRenderSettings out;
  switch (s.sampler()) {
    case v1::SAMPLER_UNSPECIFIED:
    case v1::SAMPLER_SOBOL:
      out.sampler = SamplerKind::kSobol;
      break;
    case v1::SAMPLER_INDEPENDENT:
      out.sampler = SamplerKind::kIndependent;
      break;
    default:
      throw InputError(field + ".sampler: must be SAMPLER_SOBOL or SAMPLER_INDEPENDENT");
  }
  switch (s.integrator()) {
    case v1::INTEGRATOR_PATH:
      out.integrator = IntegratorKind::kPath;
      return out;
    case v1::INTEGRATOR_PHOTONMAP:
      out.integrator = IntegratorKind::kPhotonMap;
      break;
    default:
      throw InputError(field + ".integrator: must be INTEGRATOR_PATH or INTEGRATOR_PHOTONMAP");
  }
  const v1::PhotonMapSettings& pm = s.photon_map();
  const std::string f = field + ".photon_map";
  RequireAtLeastOne(pm.photons(), f + ".photons");
  if (pm.photons() > kMaxPhotonsPerMap)
    throw LimitError(f + ".photons: " + std::to_string(pm.photons()) + " exceeds the limit " +
                     std::to_string(kMaxPhotonsPerMap));
  RequireAtLeastOne(pm.k(), f + ".k");
  if (pm.k() > kMaxK) throw LimitError(f + ".k: exceeds the limit " + std::to_string(kMaxK));
  out.photons = pm.photons();
  out.k = int(pm.k());
  out.structure = pm.structure() == v1::MAP_STRUCTURE_GRID            ? PhotonMapKind::kGrid
                  : pm.structure() == v1::MAP_STRUCTURE_BUCKET_KDTREE ? PhotonMapKind::kBucketKdTree
                                                                      : PhotonMapKind::kKdTree;
  if (pm.structure() < 0 || pm.structure() > v1::MAP_STRUCTURE_BUCKET_KDTREE)
    throw InputError(f + ".structure: unknown value");
  switch (pm.caustic()) {
    case v1::CAUSTIC_MODE_UNSPECIFIED:
    case v1::CAUSTIC_MODE_AUTO:
      out.caustic = CausticMapMode::kAuto;
      break;
    case v1::CAUSTIC_MODE_ON:
      out.caustic = CausticMapMode::kOn;
      break;
    case v1::CAUSTIC_MODE_OFF:
      out.caustic = CausticMapMode::kOff;
      break;
    default:
      throw InputError(f + ".caustic: unknown value");
  }
  if (!(pm.caustic_radius() >= 0.0) || !std::isfinite(pm.caustic_radius()))
    throw InputError(f + ".caustic_radius: must be a finite number >= 0");
  out.caustic_radius = float(pm.caustic_radius());
  if (pm.glossy_depth() > 64) throw InputError(f + ".glossy_depth: must be <= 64");
  out.glossy_depth = int(pm.glossy_depth());
  switch (pm.direction_test()) {
    case v1::DIRECTION_TEST_UNSPECIFIED:
    case v1::DIRECTION_TEST_IN_QUERY:
      out.direction_test = FeasibilityTest::kInQuery;
      break;
    case v1::DIRECTION_TEST_AFTER_QUERY:
      out.direction_test = FeasibilityTest::kAfterQuery;
      break;
    case v1::DIRECTION_TEST_NONE:
      out.direction_test = FeasibilityTest::kNone;
      break;
    default:
      throw InputError(f + ".direction_test: unknown value");
  }
  switch (pm.direct()) {
    case v1::DIRECT_LIGHT_UNSPECIFIED:
    case v1::DIRECT_LIGHT_AUTO:
      out.direct.reset();
      break;
    case v1::DIRECT_LIGHT_PHOTON_MAP:
      out.direct = DirectLightMode::kNone;
      break;
    case v1::DIRECT_LIGHT_MONTE_CARLO:
      out.direct = DirectLightMode::kMonteCarlo;
      break;
    case v1::DIRECT_LIGHT_PHOTON_DIRECT:
      out.direct = DirectLightMode::kPhotonDirect;
      break;
    default:
      throw InputError(f + ".direct: unknown value");
  }
  if (pm.has_shadow_rays()) {
    if (pm.shadow_rays() < 1 || pm.shadow_rays() > kMaxShadowRays)
      throw InputError(f + ".shadow_rays: must be in 1.." + std::to_string(kMaxShadowRays));
    out.shadow_rays = int(pm.shadow_rays());
  }
  if (!(pm.light_uniform_fraction() >= 0.0 && pm.light_uniform_fraction() <= 1.0))
    throw InputError(f + ".light_uniform_fraction: must be in [0, 1]");
  out.light_uniform_fraction = float(pm.light_uniform_fraction());
  if (pm.has_photon_direct_k()) {
    if (pm.photon_direct_k() < 1 || pm.photon_direct_k() > kMaxK)
      throw InputError(f + ".photon_direct_k: must be in 1.." + std::to_string(kMaxK));
    out.photon_direct_k = int(pm.photon_direct_k());
  }
  switch (pm.non_contributing()) {
    case v1::NON_CONTRIBUTING_UNSPECIFIED:
    case v1::NON_CONTRIBUTING_ONE_RANDOM:
      out.non_contributing = NonContributingMode::kOneRandom;
      break;
    case v1::NON_CONTRIBUTING_EACH:
      out.non_contributing = NonContributingMode::kEachOne;
      break;
    default:
      throw InputError(f + ".non_contributing: unknown value");
  }
  if (pm.has_photon_direct_cache()) {
    if (!(pm.photon_direct_cache() >= 0.0 && pm.photon_direct_cache() <= 1.0))
      throw InputError(f + ".photon_direct_cache: must be in [0, 1]");
    out.photon_direct_cache = float(pm.photon_direct_cache());
  }
  if (pm.local_pass_rays() > kMaxShadowRays)
    throw InputError(f + ".local_pass_rays: must be <= " + std::to_string(kMaxShadowRays));
  out.local_pass_rays = int(pm.local_pass_rays());
  switch (pm.local_pass_lookup()) {
    case v1::LOCAL_PASS_LOOKUP_UNSPECIFIED:
    case v1::LOCAL_PASS_LOOKUP_FULL:
      out.local_pass_lookup = LocalPassLookup::kFull;
      break;
    case v1::LOCAL_PASS_LOOKUP_PRECOMPUTED:
      out.local_pass_lookup = LocalPassLookup::kPrecomputed;
      break;
    default:
      throw InputError(f + ".local_pass_lookup: unknown value");
  }
  switch (pm.site_occlusion_test()) {
    case v1::SITE_OCCLUSION_TEST_UNSPECIFIED:
    case v1::SITE_OCCLUSION_TEST_ON:
      out.site_occlusion_test = true;
      break;
    case v1::SITE_OCCLUSION_TEST_OFF:
      // Without precomputed sites there is nothing to switch off: refuse instead of ignoring it.
      if (out.local_pass_lookup != LocalPassLookup::kPrecomputed)
        throw InputError(
            f +
            ".site_occlusion_test: OFF applies to the precomputed sites only; set "
            "local_pass_lookup = LOCAL_PASS_LOOKUP_PRECOMPUTED (--local-pass-lookup precomputed)");
      if (pm.local_pass_rays() == 0)
        throw InputError(f +
                         ".site_occlusion_test: OFF applies to the local pass's precomputed sites; set "
                         "local_pass_rays > 0 (--local-pass N)");
      // The camera path's test is applied to the sites' estimates too (they are the same
      // estimates, precomputed), so OFF would be silently ignored.
      if (pm.occlusion_test())
        throw InputError(f +
                         ".site_occlusion_test: OFF contradicts occlusion_test = true, which tests the "
                         "sites' photons too; drop one of them");
      out.site_occlusion_test = false;
      break;
    default:
      throw InputError(f + ".site_occlusion_test: unknown value");
  }
  if (!(pm.irradiance_cache_error() >= 0.0 && pm.irradiance_cache_error() <= 1.0))
    throw InputError(f + ".irradiance_cache_error: must be in [0, 1] (0 = off)");
  // The cache stores the local pass's gathers: without one it would be silently ignored.
  if (pm.irradiance_cache_error() > 0.0 && pm.local_pass_rays() == 0)
    throw InputError(
        f +
        ".irradiance_cache_error: caches the local pass's gathers; set local_pass_rays > 0 (--local-pass N)");
  out.irradiance_cache_error = float(pm.irradiance_cache_error());
  out.occlusion_test = pm.occlusion_test();
  if (pm.adaptive_k_min() > pm.k())
    throw InputError(f + ".adaptive_k_min: must be <= k (" + std::to_string(pm.k()) + ")");
  out.adaptive_k_min = int(pm.adaptive_k_min());
  switch (pm.kd_split()) {
    case v1::KD_SPLIT_UNSPECIFIED:
    case v1::KD_SPLIT_WIDEST:
      out.kd_split = KdSplitRule::kWidestExtent;
      break;
    case v1::KD_SPLIT_CYCLE:
      out.kd_split = KdSplitRule::kLevelCycle;
      break;
    default:
      throw InputError(f + ".kd_split: unknown value");
  }
  switch (pm.map_tracing()) {
    case v1::MAP_TRACING_UNSPECIFIED:
    case v1::MAP_TRACING_AUTO:
      out.map_tracing = MapTracingMode::kAuto;
      break;
    case v1::MAP_TRACING_LOCAL:
      out.map_tracing = MapTracingMode::kLocal;
      break;
    case v1::MAP_TRACING_DISTRIBUTED:
      if (out.structure != PhotonMapKind::kKdTree)
        throw InputError(
            f + ".map_tracing: distributed tracing needs the kd-tree structure (only its maps travel)");
      out.map_tracing = MapTracingMode::kDistributed;
      break;
    default:
      throw InputError(f + ".map_tracing: unknown value");
  }
  switch (pm.importance()) {
    case v1::IMPORTANCE_MODE_UNSPECIFIED:
    case v1::IMPORTANCE_MODE_OFF:
      out.importance = ImportanceMode::kOff;
      break;
    case v1::IMPORTANCE_MODE_ON:
      out.importance = ImportanceMode::kOn;
      break;
    case v1::IMPORTANCE_MODE_AUTO:
      out.importance = ImportanceMode::kAuto;
      break;
    default:
      throw InputError(f + ".importance: unknown value");
  }
  if (pm.has_importance_min_probability()) {
    if (!(pm.importance_min_probability() > 0.0 && pm.importance_min_probability() <= 1.0))
      throw InputError(f + ".importance_min_probability: must be in (0, 1] (photons everywhere need p > 0)");
    out.importance_min_probability = float(pm.importance_min_probability());
  }
  if (pm.has_importance_strength()) {
    if (!(pm.importance_strength() > 0.0 && pm.importance_strength() <= 1e6))
      throw InputError(f + ".importance_strength: must be in (0, 1e6]");
    out.importance_strength = float(pm.importance_strength());
  }
  if (pm.importons() > kMaxImportons)
    throw InputError(f + ".importons: must be <= " + std::to_string(kMaxImportons) + " (0 = one per pixel)");
  out.importons = pm.importons();
  // Wald 1999, §4.6: caustic splitting.
  if (pm.caustic_split() > kMaxCausticSplit)
    throw InputError(f + ".caustic_split: must be in [1, " + std::to_string(kMaxCausticSplit) +
                     "] (0 or 1 = off)");
  out.caustic_split = std::max<uint32_t>(1, pm.caustic_split());
  switch (pm.caustic_split_method()) {
    case v1::CAUSTIC_SPLIT_METHOD_UNSPECIFIED:
    case v1::CAUSTIC_SPLIT_METHOD_BRUTE:
      out.caustic_split_method = CausticSplitMethod::kBrute;
      break;
    case v1::CAUSTIC_SPLIT_METHOD_METROPOLIS:
      out.caustic_split_method = CausticSplitMethod::kMetropolis;
      break;
    default:
      throw InputError(f + ".caustic_split_method: unknown value");
  }
  if (out.caustic_split > 1 && out.caustic_split_method == CausticSplitMethod::kBrute &&
      out.photons * out.caustic_split > kMaxPhotonsPerMap)
    throw LimitError(
        f + ".caustic_split: photons × caustic_split = " + std::to_string(out.photons * out.caustic_split) +
        " photons emitted exceeds the limit " + std::to_string(kMaxPhotonsPerMap));
  if (out.caustic_split > 1 && out.caustic_split_method == CausticSplitMethod::kMetropolis &&
      out.importance != ImportanceMode::kOff)
    throw InputError(
        f +
        ".caustic_split_method: Metropolis splitting is not combined with importance-driven maps "
        "(its mutated chains would need their own acceptance draws); use brute or importance off");
  if (out.map_tracing == MapTracingMode::kDistributed && out.importance != ImportanceMode::kOff)
    throw InputError(f +
                     ".map_tracing: distributed tracing does not build importance-driven maps (their "
                     "importons come from the camera); use map_tracing auto or local with importance");
  return out;
}

void SettingsToProto(const JobRenderSettings& s, v1::RenderSettings* out) {
  out->set_integrator(s.integrator == IntegratorKind::kPath ? v1::INTEGRATOR_PATH : v1::INTEGRATOR_PHOTONMAP);
  out->set_sampler(s.sampler == SamplerKind::kIndependent ? v1::SAMPLER_INDEPENDENT : v1::SAMPLER_SOBOL);
  if (s.integrator == IntegratorKind::kPath) return;
  v1::PhotonMapSettings* pm = out->mutable_photon_map();
  pm->set_photons(s.photons);
  pm->set_k(uint32_t(s.k));
  pm->set_structure(s.structure == PhotonMapKind::kGrid           ? v1::MAP_STRUCTURE_GRID
                    : s.structure == PhotonMapKind::kBucketKdTree ? v1::MAP_STRUCTURE_BUCKET_KDTREE
                                                                  : v1::MAP_STRUCTURE_KDTREE);
  pm->set_caustic(s.caustic == CausticMapMode::kOn    ? v1::CAUSTIC_MODE_ON
                  : s.caustic == CausticMapMode::kOff ? v1::CAUSTIC_MODE_OFF
                                                      : v1::CAUSTIC_MODE_AUTO);
  pm->set_caustic_radius(s.caustic_radius);
  pm->set_glossy_depth(uint32_t(s.glossy_depth));
  pm->set_direction_test(s.direction_test == FeasibilityTest::kAfterQuery ? v1::DIRECTION_TEST_AFTER_QUERY
                         : s.direction_test == FeasibilityTest::kNone     ? v1::DIRECTION_TEST_NONE
                                                                          : v1::DIRECTION_TEST_IN_QUERY);
  pm->set_direct(!s.direct                                     ? v1::DIRECT_LIGHT_AUTO
                 : *s.direct == DirectLightMode::kMonteCarlo   ? v1::DIRECT_LIGHT_MONTE_CARLO
                 : *s.direct == DirectLightMode::kPhotonDirect ? v1::DIRECT_LIGHT_PHOTON_DIRECT
                                                               : v1::DIRECT_LIGHT_PHOTON_MAP);
  pm->set_shadow_rays(uint32_t(s.shadow_rays));
  pm->set_light_uniform_fraction(s.light_uniform_fraction);
  pm->set_photon_direct_k(uint32_t(s.photon_direct_k));
  pm->set_non_contributing(s.non_contributing == NonContributingMode::kEachOne
                               ? v1::NON_CONTRIBUTING_EACH
                               : v1::NON_CONTRIBUTING_ONE_RANDOM);
  pm->set_photon_direct_cache(s.photon_direct_cache);
  pm->set_local_pass_rays(uint32_t(s.local_pass_rays));
  pm->set_local_pass_lookup(s.local_pass_lookup == LocalPassLookup::kPrecomputed
                                ? v1::LOCAL_PASS_LOOKUP_PRECOMPUTED
                                : v1::LOCAL_PASS_LOOKUP_FULL);
  if (!s.site_occlusion_test) pm->set_site_occlusion_test(v1::SITE_OCCLUSION_TEST_OFF);  // ON is the default
  pm->set_irradiance_cache_error(s.irradiance_cache_error);
  pm->set_occlusion_test(s.occlusion_test);
  pm->set_adaptive_k_min(uint32_t(s.adaptive_k_min));
  pm->set_kd_split(s.kd_split == KdSplitRule::kLevelCycle ? v1::KD_SPLIT_CYCLE : v1::KD_SPLIT_WIDEST);
  if (s.map_tracing !=
      MapTracingMode::kAuto)  // auto stays unset: specs stored before the setting existed read alike
    pm->set_map_tracing(s.map_tracing == MapTracingMode::kLocal ? v1::MAP_TRACING_LOCAL
                                                                : v1::MAP_TRACING_DISTRIBUTED);
  pm->set_importance(s.importance == ImportanceMode::kOn     ? v1::IMPORTANCE_MODE_ON
                     : s.importance == ImportanceMode::kAuto ? v1::IMPORTANCE_MODE_AUTO
                                                             : v1::IMPORTANCE_MODE_OFF);
  pm->set_importance_min_probability(s.importance_min_probability);
  pm->set_importance_strength(s.importance_strength);
  pm->set_importons(s.importons);
  // Unset when off, so specs without splitting serialise exactly as before the setting existed.
  if (s.caustic_split > 1) {
    pm->set_caustic_split(s.caustic_split);
    pm->set_caustic_split_method(s.caustic_split_method == CausticSplitMethod::kMetropolis
                                     ? v1::CAUSTIC_SPLIT_METHOD_METROPOLIS
                                     : v1::CAUSTIC_SPLIT_METHOD_BRUTE);
  }
}

PlanSpec PlanFromProto(const v1::Plan& p, const std::string& field) {
  PlanSpec out;
  auto check_spp = [](uint32_t spp, const std::string& f) {
    RequireAtLeastOne(spp, f);
    if (spp > kMaxSamplesPerPixel)
      throw LimitError(f + ": exceeds the limit " + std::to_string(kMaxSamplesPerPixel));
  };
  switch (p.kind_case()) {
    case v1::Plan::kMultipleMaps:
      out.kind = PlanKind::kMultipleMaps;
      out.maps = p.multiple_maps().maps();
      out.samples_per_pixel = p.multiple_maps().samples_per_pixel();
      out.tile_size = p.multiple_maps().tile_size();
      out.tail_tile_size = p.multiple_maps().tail_tile_size();
      RequireAtLeastOne(out.maps, field + ".multiple_maps.maps");
      check_spp(out.samples_per_pixel, field + ".multiple_maps.samples_per_pixel");
      break;
    case v1::Plan::kMapsInTurn:
      out.kind = PlanKind::kMapsInTurn;
      out.samples_per_pixel = p.maps_in_turn().samples_per_pixel();
      out.tile_size = p.maps_in_turn().tile_size();
      check_spp(out.samples_per_pixel, field + ".maps_in_turn.samples_per_pixel");
      break;
    case v1::Plan::kSkipping:
      out.kind = PlanKind::kSkipping;
      out.stride = p.skipping().stride();
      out.rounds = p.skipping().rounds();
      out.samples_per_pixel = p.skipping().samples_per_pixel();
      RequireAtLeastOne(out.stride, field + ".skipping.stride");
      RequireAtLeastOne(out.rounds, field + ".skipping.rounds");
      check_spp(out.samples_per_pixel, field + ".skipping.samples_per_pixel");
      break;
    case v1::Plan::kHierarchical: {
      const v1::Hierarchical& h = p.hierarchical();
      out.kind = PlanKind::kHierarchical;
      out.levels = h.levels();
      out.dims = h.dims();
      out.base_samples = h.base_samples();
      out.min_samples = h.min_samples();
      out.decay = h.decay();
      out.localize_threshold = h.localize_threshold();
      out.localize_contrast = h.localize_contrast();
      out.samples_per_pixel = h.samples_per_pixel();
      out.tile_size = h.rows_per_task();
      check_spp(out.samples_per_pixel, field + ".hierarchical.samples_per_pixel");
      switch (h.part()) {
        case v1::HIERARCHY_PART_ALL:
          out.hierarchy_part = HierarchyPart::kAll;
          break;
        case v1::HIERARCHY_PART_INDIRECT:
          out.hierarchy_part = HierarchyPart::kIndirect;
          break;
        default:
          throw InputError(field + ".hierarchical.part: unknown value " + std::to_string(int(h.part())));
      }
      out.direct_samples = h.direct_samples_per_pixel();
      if (out.direct_samples > kMaxSamplesPerPixel)
        throw LimitError(field + ".hierarchical.direct_samples_per_pixel: exceeds the limit " +
                         std::to_string(kMaxSamplesPerPixel));
      // The rest (ranges, map count) is checked by ValidatePlan with the image size.
      break;
    }
    case v1::Plan::kAutoPlan:
      throw InputError(field +
                       ".auto_plan: not resolved (the coordinator replaces it by the plan it chooses)");
    default:
      throw InputError(field +
                       ": one of multiple_maps, maps_in_turn, skipping, hierarchical, auto_plan is required");
  }
  return out;
}

void PlanToProto(const PlanSpec& p, v1::Plan* out) {
  switch (p.kind) {
    case PlanKind::kMultipleMaps: {
      auto* m = out->mutable_multiple_maps();
      m->set_maps(p.maps);
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_tile_size(p.tile_size);
      m->set_tail_tile_size(p.tail_tile_size);
      break;
    }
    case PlanKind::kMapsInTurn: {
      auto* m = out->mutable_maps_in_turn();
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_tile_size(p.tile_size);
      break;
    }
    case PlanKind::kSkipping: {
      auto* m = out->mutable_skipping();
      m->set_stride(p.stride);
      m->set_rounds(p.rounds);
      m->set_samples_per_pixel(p.samples_per_pixel);
      break;
    }
    case PlanKind::kHierarchical: {
      auto* m = out->mutable_hierarchical();
      m->set_levels(p.levels);
      m->set_dims(p.dims);
      m->set_base_samples(p.base_samples);
      m->set_min_samples(p.min_samples);
      m->set_decay(p.decay);
      m->set_localize_threshold(p.localize_threshold);
      m->set_localize_contrast(p.localize_contrast);
      m->set_samples_per_pixel(p.samples_per_pixel);
      m->set_rows_per_task(p.tile_size);
      // Unset for part all: such plans serialise exactly as before the setting existed.
      if (p.hierarchy_part == HierarchyPart::kIndirect) m->set_part(v1::HIERARCHY_PART_INDIRECT);
      m->set_direct_samples_per_pixel(p.direct_samples);
      break;
    }
  }
}

PixelSubset PixelSubsetFromProto(const v1::PixelSubset& p, const std::string& field) {
  PixelSubset out;
  switch (p.kind_case()) {
    case v1::PixelSubset::kTile:
      out.kind = PixelSubset::Kind::kTile;
      out.x0 = p.tile().x0();
      out.y0 = p.tile().y0();
      out.x1 = p.tile().x1();
      out.y1 = p.tile().y1();
      break;
    case v1::PixelSubset::kPermutationStride:
      out.kind = PixelSubset::Kind::kPermutationStride;
      out.permutation_seed = p.permutation_stride().permutation_seed();
      out.offset = p.permutation_stride().offset();
      out.stride = p.permutation_stride().stride();
      break;
    case v1::PixelSubset::kHierarchyLevel:
      out.kind = PixelSubset::Kind::kHierarchyLevel;
      out.level = p.hierarchy_level().level();
      out.levels = p.hierarchy_level().levels();
      out.dims = p.hierarchy_level().dims();
      out.y0 = p.hierarchy_level().y0();
      out.y1 = p.hierarchy_level().y1();
      break;
    case v1::PixelSubset::kList:
      out.kind = PixelSubset::Kind::kList;
      out.list.assign(p.list().indices().begin(), p.list().indices().end());
      break;
    default:
      throw InputError(field + ": tile, permutation_stride, hierarchy_level or list is required");
  }
  return out;
}

void PixelSubsetToProto(const PixelSubset& p, v1::PixelSubset* out) {
  if (p.kind == PixelSubset::Kind::kTile) {
    auto* t = out->mutable_tile();
    t->set_x0(p.x0);
    t->set_y0(p.y0);
    t->set_x1(p.x1);
    t->set_y1(p.y1);
  } else if (p.kind == PixelSubset::Kind::kHierarchyLevel) {
    auto* h = out->mutable_hierarchy_level();
    h->set_level(p.level);
    h->set_levels(p.levels);
    h->set_dims(p.dims);
    h->set_y0(p.y0);
    h->set_y1(p.y1);
  } else if (p.kind == PixelSubset::Kind::kList) {
    out->mutable_list()->mutable_indices()->Add(p.list.begin(), p.list.end());
  } else {
    auto* s = out->mutable_permutation_stride();
    s->set_permutation_seed(p.permutation_seed);
    s->set_offset(p.offset);
    s->set_stride(p.stride);
  }
}

TaskSpec TaskSpecFromProto(const v1::Task& t) {
  TaskSpec s;
  s.task_id = t.task_id();
  s.map_index = t.map_index();
  s.map_seed = t.map_seed();
  s.pixel_seed = t.pixel_seed();
  s.pixels = PixelSubsetFromProto(t.pixels(), "task.pixels");
  s.sample_begin = t.sample_begin();
  s.sample_end = t.sample_end();
  if (s.sample_end <= s.sample_begin) throw InputError("task.sample_end: must be > sample_begin");
  switch (t.part()) {
    case v1::RADIANCE_PART_ALL:
      s.part = RadiancePart::kAll;
      break;
    case v1::RADIANCE_PART_MAPPED:
      s.part = RadiancePart::kMapped;
      break;
    case v1::RADIANCE_PART_UNMAPPED:
      s.part = RadiancePart::kUnmapped;
      break;
    default:
      throw InputError("task.part: unknown value " + std::to_string(int(t.part())));
  }
  return s;
}

void TaskSpecToProto(const TaskSpec& spec, v1::Task* out) {
  out->set_task_id(spec.task_id);
  out->set_map_index(spec.map_index);
  out->set_map_seed(spec.map_seed);
  out->set_pixel_seed(spec.pixel_seed);
  PixelSubsetToProto(spec.pixels, out->mutable_pixels());
  out->set_sample_begin(spec.sample_begin);
  out->set_sample_end(spec.sample_end);
  out->set_part(spec.part == RadiancePart::kMapped     ? v1::RADIANCE_PART_MAPPED
                : spec.part == RadiancePart::kUnmapped ? v1::RADIANCE_PART_UNMAPPED
                                                       : v1::RADIANCE_PART_ALL);
}

bool ResolveAutoPlan(v1::JobSpec* spec, int width, int height, int caustic_paths, uint32_t workers,
                     bool maps_can_be_shipped, const std::string& field) {
  if (!spec->plan().has_auto_plan()) return false;
  const v1::PlanAuto a = spec->plan().auto_plan();
  const std::string f = field + ".plan.auto_plan";
  const JobRenderSettings settings = SettingsFromProto(spec->settings(), field + ".settings");
  PlanChoiceInput in;
  in.width = width;
  in.height = height;
  in.photon_map = settings.integrator == IntegratorKind::kPhotonMap;
  in.photon_budget = in.photon_map ? settings.photons : 0;
  if (a.samples_per_pixel() > kMaxSamplesPerPixel)
    throw LimitError(f + ".samples_per_pixel: exceeds the limit " + std::to_string(kMaxSamplesPerPixel));
  in.samples_per_pixel = a.samples_per_pixel();
  in.workers = a.workers() > 0 ? a.workers() : workers;
  in.caustic_map = in.photon_map && (settings.caustic == CausticMapMode::kOn ||
                                     (settings.caustic == CausticMapMode::kAuto && caustic_paths != 0));
  in.time_budget_seconds = spec->stop().time_budget_seconds();
  in.target_noise_rms = spec->stop().target_noise_rms();
  in.maps_can_be_shipped = maps_can_be_shipped;
  PlanChoice choice;
  try {
    choice = ChoosePlan(in);
  } catch (const InputError& e) {
    // ChoosePlan names fields relative to the job ("plan.auto.workers"); the wire's message is
    // auto_plan, and the budget is a setting.
    std::string msg = e.what();
    if (msg.rfind("plan.auto.", 0) == 0)
      msg = f + "." + msg.substr(10);
    else
      msg = field + "." + msg;
    throw InputError(msg);
  }
  v1::AutoPlanChoice record;
  record.set_reason(choice.reason);
  record.set_workers(in.workers);
  record.set_photon_budget(in.photon_budget);
  record.set_photons_per_map(choice.photons_per_map);
  record.set_caustic_map(in.caustic_map);
  record.set_maps_can_be_shipped(maps_can_be_shipped);
  spec->mutable_plan()->Clear();
  PlanToProto(choice.plan, spec->mutable_plan());
  *spec->mutable_plan()->mutable_chosen_by_auto() = record;
  if (in.photon_map) spec->mutable_settings()->mutable_photon_map()->set_photons(choice.photons_per_map);
  return true;
}

void BundleToProto(const SceneBundle& bundle, v1::SceneBundle* out) {
  out->set_entry(bundle.entry);
  for (const auto& [path, content] : bundle.files) {
    v1::SceneFile* f = out->add_files();
    f->set_path(path);
    f->set_content(content);
  }
}

}  // namespace pf
