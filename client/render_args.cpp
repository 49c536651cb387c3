#include "client/render_args.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>
#include <variant>

#include "common/core/error.h"
#include "common/photon/photon_tracer.h"
#include "common/plan/plan_choice.h"
#include "common/scene/manifest.h"
#include "common/scene/scene_loader.h"
#include "proto/convert.h"

namespace pf {
namespace v1 = photonfarm::v1;

namespace {

// X,Y,Z in double (a camera point is a world point, common/scene/scene_frame.h); finite as a
// float too, as every world coordinate.
Vec3d ParsePoint(const std::string& text, const char* option) {
  Vec3d v;
  char c1 = 0, c2 = 0;
  std::istringstream in(text);
  if (!(in >> v.x >> c1 >> v.y >> c2 >> v.z) || c1 != ',' || c2 != ',' || !IsFinite(Vec3(v)) || !in.eof())
    throw InputError(std::string(option) + ": expected X,Y,Z (three finite numbers), got '" + text + "'");
  return v;
}

Vec3 ParseVec3(const std::string& text, const char* option) {
  Vec3 v;
  char c1 = 0, c2 = 0;
  std::istringstream in(text);
  if (!(in >> v.x >> c1 >> v.y >> c2 >> v.z) || c1 != ',' || c2 != ',' || !IsFinite(v) || !in.eof())
    throw InputError(std::string(option) + ": expected X,Y,Z (three finite numbers), got '" + text + "'");
  return v;
}

void ParseResolution(const std::string& text, int& width, int& height) {
  char x = 0;
  std::istringstream in(text);
  if (!(in >> width >> x >> height) || (x != 'x' && x != 'X') || !in.eof() || width <= 0 || height <= 0 ||
      width > int(kMaxImageSide) || height > int(kMaxImageSide))
    throw InputError("--res: expected WxH with 1.." + std::to_string(kMaxImageSide) + " each, got '" + text +
                     "'");
  if (uint64_t(width) * uint64_t(height) > kMaxImagePixels)
    throw InputError("--res: " + text + " is more than the farm's " + std::to_string(kMaxImagePixels) +
                     " pixels");
}

// --tail-tile: -1 = on a farm of several workers (--workers N > 1 without --local-only, or submit:
// any number) half the tile when that is a multiple of the pixel block (16), so the image is the
// same as without; 0 elsewhere (one process renders a tile's pixels on all its threads and one
// worker has nobody waiting for it: neither has a tail to shorten). `--plan auto` decides on the
// coordinator (plan_choice.cpp), with the same rule.
uint32_t TailTileFor(const RenderArgs& a) {
  if (a.tail_tile >= 0) return uint32_t(a.tail_tile);
  const bool farm = (a.workers > 1 && !a.local_only) || a.submit;
  const uint32_t half = a.tile / 2;
  return farm && a.tile >= 32 && half % 16 == 0 ? half : 0;
}

}  // namespace

std::string FormatVec(const Vec3& v) {
  return fmt::format("{},{},{}", v.x, v.y, v.z);
}

std::string FormatVec(const Vec3d& v) {
  // A point that is a float (every camera of a scene around the origin) prints as before, as
  // the shortest text of that float; others as the shortest text of the double.
  if (Vec3d(Vec3(v)) == v) return FormatVec(Vec3(v));
  return fmt::format("{},{},{}", v.x, v.y, v.z);
}

void ApplyManifestSettings(RenderArgs& a) {
  if (std::filesystem::path(a.scene).extension() != ".json") return;
  const SceneManifest manifest = LoadManifest(a.scene);
  auto number = [&](const char* key, double lo, double hi) -> std::optional<double> {
    auto it = manifest.settings.find(key);
    if (it == manifest.settings.end() || !std::holds_alternative<double>(it->second)) return std::nullopt;
    const double v = std::get<double>(it->second);
    if (!(v >= lo && v <= hi) || v != std::floor(v))
      throw InputError(a.scene + ": settings." + key + ": expected a whole number in " +
                       fmt::format("{}..{}", lo, hi) + ", got " + fmt::format("{}", v));
    return v;
  };
  // A plan's --spp means samples per map or per task (see --spp): only a plain render takes the
  // manifest's, which is a per-pixel count.
  const bool plain = a.plan.empty() && !a.local_only && a.workers == 0;
  if (auto v = number("spp", 1, kMaxSamplesPerPixel); v && !a.spp_given && plain) {
    a.spp = uint32_t(*v);
    spdlog::info("spp = {} from the manifest's settings (--spp overrides)", a.spp);
  }
  if (a.integrator != "photonmap") return;
  if (auto v = number("photons", 1, double(kMaxPhotonsPerMap)); v && !a.photons_given) {
    a.photons = uint64_t(*v);
    spdlog::info("photons = {} from the manifest's settings (--photons overrides)", a.photons);
  }
  if (auto v = number("k", 1, kMaxK); v && !a.k_given) {
    a.k = int(*v);
    spdlog::info("k = {} from the manifest's settings (--k overrides)", a.k);
  }
}

void AddSceneOptions(CLI::App* app, RenderArgs& a) {
  app->add_option("scene", a.scene, "Scene manifest (.json) or geometry file (.mgf, .obj)")->required();
  app->add_option("--integrator", a.integrator,
                  "path = reference path tracer (NEE + MIS + RR); photonmap = standalone photon-map "
                  "estimate in a distribution ray tracer (Wald 1999, 2.5)")
      ->capture_default_str()
      ->check(CLI::IsMember({"path", "photonmap"}));
  app->add_option("--sampler", a.sampler,
                  "sobol = padded Owen-scrambled Sobol points (randomised quasi-Monte Carlo: pixel position, "
                  "lights, BSDFs, roulette, gather rays, photon emission and scattering); independent = "
                  "independent uniform numbers, to compare (docs/renderer.md, 'Sampling')")
      ->capture_default_str()
      ->check(CLI::IsMember({"sobol", "independent"}));
  app->add_option("--spp", a.spp,
                  "Samples per pixel (with --plan: per map for multiple-maps, = number of maps for "
                  "maps-in-turn, per task and pixel for skipping)")
      ->capture_default_str()
      ->check(CLI::Range(1u, kMaxSamplesPerPixel));
  app->add_option("--seed", a.seed, "Seed: the same seed gives the same image on any thread or worker count")
      ->capture_default_str();
  app->add_option("--camera", a.camera_name, "Named camera of the manifest (default: its first)");
  app->add_option("--eye", a.eye, "Camera position X,Y,Z (overrides the manifest)");
  app->add_option("--look-at", a.look_at, "Point the camera looks at X,Y,Z");
  app->add_option("--up", a.up, "Up vector X,Y,Z (image right = forward x up)");
  app->add_option("--fov", a.fov, "Vertical field of view in degrees")->check(CLI::Range(0.01f, 179.9f));
  app->add_option("--res", a.res, "Resolution WxH, e.g. 640x480");
  // Everything from here on configures the photon-map integrator only: one help section, and
  // RejectPhotonMapOptionsForPath finds them by it.
  const size_t first_photon_map_option = app->get_options().size();
  app->add_option("--photons", a.photons, "photonmap: photons emitted per map")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(1), kMaxPhotonsPerMap));
  app->add_option("--k", a.k, "photonmap: nearest photons per radiance estimate")
      ->capture_default_str()
      ->check(CLI::Range(1, int(kMaxK)));
  app->add_option(
         "--map", a.map,
         "photonmap: kdtree (left-balanced, 2.3), grid (2.4) or bucket (unbalanced kd-tree with SIMD "
         "buckets, the fastest queries)")
      ->capture_default_str()
      ->check(CLI::IsMember({"kdtree", "grid", "bucket"}));
  app->add_option("--kd-split", a.kd_split,
                  "kdtree split axis: widest (extent; faster in rooms, 2.3 footnote) or cycle (level % 3)")
      ->capture_default_str()
      ->check(CLI::IsMember({"cycle", "widest"}));
  app->add_option("--caustic-map", a.caustic,
                  "auto = only when the scene has specular/glossy surfaces; on; off")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "on", "off"}));
  app->add_option("--caustic-radius", a.caustic_radius,
                  "photonmap: max caustic search radius (default 1% of the scene diagonal)");
  app->add_option("--glossy-depth", a.glossy_depth,
                  "photonmap: glossy bounces followed before the map estimates the glossy lobe")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  app->add_option("--direction-test", a.direction_test,
                  "photonmap: photon direction vs normal test (4.1): in-query, after, none")
      ->capture_default_str()
      ->check(CLI::IsMember({"in-query", "after", "none"}));
  app->add_option(
         "--direct", a.direct,
         "photonmap: direct light (4.2). photon-map = from the map (standalone, 2.5); mc = Monte Carlo "
         "shadow rays, per light in proportion to power (4.2.1); photon-direct = shadow rays split by "
         "the lights of the nearest direct photons (4.2.3); auto = photon-direct with " +
             std::to_string(kPhotonDirectMinLights) + "+ lights, else mc (logged)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "photon-map", "mc", "photon-direct"}));
  app->add_option("--shadow-rays", a.shadow_rays,
                  "mc: shadow rays per shading point; photon-direct: N_total for the contributing lights")
      ->capture_default_str()
      ->check(CLI::Range(1, int(kMaxShadowRays)));
  app->add_option("--light-uniform", a.light_uniform,
                  "mc: fraction of shadow rays drawn uniformly over lights rather than by power (defensive "
                  "sampling: bounds the weight of dim lights)")
      ->capture_default_str()
      ->check(CLI::Range(0.0f, 1.0f));
  app->add_option("--photon-direct-k", a.photon_direct_k, "photon-direct: direct photons looked up per point")
      ->capture_default_str()
      ->check(CLI::Range(1, int(kMaxK)));
  app->add_option(
         "--non-contributing", a.non_contributing,
         "photon-direct: lights without photons nearby get one sample in total, to one of them chosen "
         "by their photon count (one-random), or one each (each); both unbiased")
      ->capture_default_str()
      ->check(CLI::IsMember({"one-random", "each"}));
  app->add_option("--photon-direct-cache", a.photon_direct_cache,
                  "photon-direct: reuse the last neighbour set within this fraction of its radius (0 = off)")
      ->capture_default_str()
      ->check(CLI::Range(0.0f, 1.0f));
  app->add_option(
         "--local-pass", a.local_pass,
         "photonmap: final gathering rays per shading point, photon map at their hits (4.3; 0 = off)")
      ->capture_default_str()
      ->check(CLI::Range(0, int(kMaxShadowRays)));
  app->add_option(
         "--local-pass-lookup", a.local_pass_lookup,
         "local pass: what a gather ray reads at its hit: full (the photon-map estimate) or precomputed "
         "(irradiance at every 4th photon, estimated once per map; one 4-nearest-site lookup, the mean of "
         "the sites visible from the hit, Christensen 1999)")
      ->capture_default_str()
      ->check(CLI::IsMember({"full", "precomputed"}));
  app->add_option("--site-occlusion-test", a.site_occlusion_test,
                  "local pass, precomputed lookup: each site's estimate drops photons whose origin the site "
                  "cannot see (4.1.1). on: no light bleeding through walls into the sites (rooms side by "
                  "side); off: faster, and no darkened corners where nothing bleeds")
      ->capture_default_str()
      ->check(CLI::IsMember({"on", "off"}));
  app->add_flag("--irradiance-cache", a.irradiance_cache,
                "local pass: irradiance caching (Ward 1988): a shading point interpolates the gathers of "
                "nearby points of its 16x16-pixel block instead of gathering, where they are close enough "
                "(--irradiance-cache-error)");
  app->add_option("--irradiance-cache-error", a.irradiance_cache_error,
                  "irradiance cache: Ward's a, the largest distance/R + normal deviation a cached gather "
                  "is reused at (smaller = more gathers, less error)")
      ->capture_default_str()
      ->check(CLI::Range(0.001f, 1.0f));
  app->add_flag("--occlusion-test", a.occlusion_test,
                "photonmap: drop found photons whose origin is not visible from the point (4.1.1; "
                "removes light bleeding through walls, one shadow ray per photon)");
  app->add_option(
         "--adaptive-k-min", a.adaptive_k_min,
         "photonmap: shrink k down to this at borders and corners by the centre-of-gravity test (4.8; "
         "0 = off)")
      ->capture_default_str()
      ->check(CLI::Range(0, int(kMaxK)));
  app->add_option(
         "--importance", a.importance,
         "photonmap: importance-driven maps (4.7): importons from the camera make an importance map; a "
         "diffuse photon hit is stored with probability p = clamp(s * importance/mean, p_min, 1) and "
         "power phi/p (unbiased; the walk goes on either way). Raise --photons with it: the map keeps "
         "fewer photons where the camera does not look. auto = on when a short pilot would drop more "
         "than 80% of the hits (logged)")
      ->capture_default_str()
      ->check(CLI::IsMember({"off", "on", "auto"}));
  app->add_option("--importance-min-probability", a.importance_min_probability,
                  "importance: p_min, the acceptance probability where nothing is seen (bounds the power "
                  "of the photons there to phi/p_min)")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 1.0));
  app->add_option("--importance-strength", a.importance_strength,
                  "importance: s, every hit whose importance is at least 1/s of the mean is stored")
      ->capture_default_str()
      ->check(CLI::Range(1e-6, 1e6));
  app->add_option("--importons", a.importons, "importance: importons per map (0 = one per pixel)")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(0), kMaxImportons));
  app->add_option("--caustic-split", a.caustic_split,
                  "photonmap: caustic splitting (4.6): S times the caustic photons, the global map unchanged "
                  "(1 = off; the thesis found 4-20 sufficient)")
      ->capture_default_str()
      ->check(CLI::Range(uint32_t(1), kMaxCausticSplit));
  app->add_option("--caustic-split-method", a.caustic_split_method,
                  "caustic splitting: brute (emit S*photons, keep non-caustic photons with 1/S at S times "
                  "the power) or metropolis (S-1 jittered copies of every singular chain; fewer rays, "
                  "start points can act as secondary lights)")
      ->capture_default_str()
      ->check(CLI::IsMember({"brute", "metropolis"}));
  const std::vector<CLI::Option*> options = app->get_options();
  for (size_t i = first_photon_map_option; i < options.size(); ++i) options[i]->group(kPhotonMapOptionGroup);
}

void RejectPhotonMapOptionsForPath(const CLI::App& cmd, const RenderArgs& a) {
  if (a.integrator != "path") return;
  for (const CLI::Option* opt : cmd.get_options())
    if (opt->get_group() == kPhotonMapOptionGroup && opt->count() > 0)
      throw CLI::ValidationError(opt->get_name(),
                                 "applies to the photon-map integrator only (add --integrator photonmap); "
                                 "the path tracer would ignore it");
}

void RenderSettingsFromArgs(const RenderArgs& a, v1::RenderSettings* rs) {
  rs->set_sampler(a.sampler == "independent" ? v1::SAMPLER_INDEPENDENT : v1::SAMPLER_SOBOL);
  if (a.integrator == "path") {
    rs->set_integrator(v1::INTEGRATOR_PATH);
    return;
  }
  rs->set_integrator(v1::INTEGRATOR_PHOTONMAP);
  v1::PhotonMapSettings* pm = rs->mutable_photon_map();
  pm->set_photons(a.photons);
  pm->set_k(uint32_t(a.k));
  pm->set_structure(a.map == "grid"     ? v1::MAP_STRUCTURE_GRID
                    : a.map == "bucket" ? v1::MAP_STRUCTURE_BUCKET_KDTREE
                                        : v1::MAP_STRUCTURE_KDTREE);
  pm->set_kd_split(a.kd_split == "cycle" ? v1::KD_SPLIT_CYCLE : v1::KD_SPLIT_WIDEST);
  pm->set_caustic(a.caustic == "on"    ? v1::CAUSTIC_MODE_ON
                  : a.caustic == "off" ? v1::CAUSTIC_MODE_OFF
                                       : v1::CAUSTIC_MODE_AUTO);
  pm->set_caustic_radius(a.caustic_radius);
  pm->set_glossy_depth(uint32_t(a.glossy_depth));
  pm->set_direction_test(a.direction_test == "none"    ? v1::DIRECTION_TEST_NONE
                         : a.direction_test == "after" ? v1::DIRECTION_TEST_AFTER_QUERY
                                                       : v1::DIRECTION_TEST_IN_QUERY);
  pm->set_direct(a.direct == "photon-map"      ? v1::DIRECT_LIGHT_PHOTON_MAP
                 : a.direct == "mc"            ? v1::DIRECT_LIGHT_MONTE_CARLO
                 : a.direct == "photon-direct" ? v1::DIRECT_LIGHT_PHOTON_DIRECT
                                               : v1::DIRECT_LIGHT_AUTO);
  pm->set_shadow_rays(uint32_t(a.shadow_rays));
  pm->set_light_uniform_fraction(a.light_uniform);
  pm->set_photon_direct_k(uint32_t(a.photon_direct_k));
  pm->set_non_contributing(a.non_contributing == "each" ? v1::NON_CONTRIBUTING_EACH
                                                        : v1::NON_CONTRIBUTING_ONE_RANDOM);
  pm->set_photon_direct_cache(a.photon_direct_cache);
  pm->set_local_pass_rays(uint32_t(a.local_pass));
  pm->set_local_pass_lookup(a.local_pass_lookup == "precomputed" ? v1::LOCAL_PASS_LOOKUP_PRECOMPUTED
                                                                 : v1::LOCAL_PASS_LOOKUP_FULL);
  if (a.site_occlusion_test == "off") pm->set_site_occlusion_test(v1::SITE_OCCLUSION_TEST_OFF);
  if (a.irradiance_cache) pm->set_irradiance_cache_error(a.irradiance_cache_error);
  pm->set_occlusion_test(a.occlusion_test);
  pm->set_adaptive_k_min(uint32_t(a.adaptive_k_min));
  if (a.map_tracing != "auto")
    pm->set_map_tracing(a.map_tracing == "local" ? v1::MAP_TRACING_LOCAL : v1::MAP_TRACING_DISTRIBUTED);
  pm->set_importance(a.importance == "on"     ? v1::IMPORTANCE_MODE_ON
                     : a.importance == "auto" ? v1::IMPORTANCE_MODE_AUTO
                                              : v1::IMPORTANCE_MODE_OFF);
  pm->set_importance_min_probability(a.importance_min_probability);
  pm->set_importance_strength(a.importance_strength);
  pm->set_importons(a.importons);
  if (a.caustic_split > 1) {
    pm->set_caustic_split(a.caustic_split);
    pm->set_caustic_split_method(a.caustic_split_method == "metropolis" ? v1::CAUSTIC_SPLIT_METHOD_METROPOLIS
                                                                        : v1::CAUSTIC_SPLIT_METHOD_BRUTE);
  }
}

JobRenderSettings ResolveAndLog(const JobRenderSettings& settings, const SceneDescription& scene) {
  std::vector<AutoChoice> choices;
  JobRenderSettings resolved = settings.Resolved(scene, &choices);
  for (const AutoChoice& c : choices) spdlog::info("auto {} = {}: {}", c.setting, c.value, c.reason);
  return resolved;
}

void AddPlanOptions(CLI::App* app, RenderArgs& a) {
  app->add_option(
         "--plan", a.plan,
         "How the image is split into tasks (Wald 1999, 4.4): multiple-maps (--maps independent maps "
         "over --tile tiles, averaged), maps-in-turn (sample i from map i), skipping (per round a "
         "seeded pixel permutation, stride^2 tasks each with its own map), hierarchical (4.5: "
         "multilevel sampling, every sample of a pixel from its own map, --levels/--dims/--base-samples/"
         "--min-samples/--decay/--localize-*; --tile = rows per task), or auto (the default of --workers and "
         "`pf submit`; --local-only defaults to multiple-maps): the coordinator picks the plan, the number "
         "of "
         "maps and photons per map from the scene, the workers and the stop rule, with --photons the budget "
         "over all maps and --spp the samples per pixel over all maps (docs/farm.md, \"Choosing the plan\")")
      ->check(CLI::IsMember({"auto", "multiple-maps", "maps-in-turn", "skipping", "hierarchical"}));
  // Which plan-shape flags were given: --plan auto chooses them itself.
  auto shape = [&a](CLI::Option* o) {
    o->each([&a, name = o->get_name()](const std::string&) { a.plan_flags_given.push_back(name); });
    return o->capture_default_str();
  };
  shape(app->add_option("--maps", a.maps, "multiple-maps: number of independent maps"));
  shape(app->add_option("--stride", a.stride, "skipping: S (S^2 tasks per round)"));
  shape(app->add_option("--rounds", a.rounds, "skipping: rounds"));
  shape(app->add_option("--tile", a.tile,
                        "multiple-maps, maps-in-turn: tile side in pixels (0 = whole image)"));
  shape(app->add_option("--tail-tile", a.tail_tile,
                        "multiple-maps: the last map's last row of tiles in tiles of this side, so a "
                        "farm's workers finish together (the image is the same); -1 = tile/2 with "
                        "--workers N > 1 or submit when that is a multiple of 16, else 0 (off)")
            ->check(CLI::Range(-1, 1 << 16)));
  shape(app->add_option("--levels", a.levels, "hierarchical: L, level-0 points every 2^L pixels (1..16)"));
  shape(app->add_option("--dims", a.dims,
                        "hierarchical: 1 = scanlines (the thesis's version), 2 = image plane"));
  shape(app->add_option("--base-samples", a.base_samples,
                        "hierarchical: n0, maps (samples) of a level-0 point"));
  shape(app->add_option("--min-samples", a.min_samples, "hierarchical: n_l never falls below this"));
  shape(app->add_option("--decay", a.decay, "hierarchical: n_l = max(min-samples, ceil(n0 / decay^l))"));
  shape(app->add_option(
      "--localize-threshold", a.localize_threshold,
      "hierarchical: tau; resample a pixel directly if |detail| > tau x the level's noise ..."));
  shape(app->add_option("--localize-contrast", a.localize_contrast,
                        "hierarchical: ... and > kappa x |interpolation| (kappa = this)"));
  shape(
      app->add_option("--hier-part", a.hier_part,
                      "hierarchical: what the levels render: all (the whole radiance) or indirect (the "
                      "photon-map part only; emission and direct light per pixel with --hier-direct-samples "
                      "samples, added at assembly: the hierarchy cures the map's low-frequency noise, direct "
                      "light is white noise a detail would add up)")
          ->check(CLI::IsMember({"all", "indirect"})));
  shape(app->add_option("--hier-direct-samples", a.hier_direct_samples,
                        "hierarchical, --hier-part indirect: emission + direct light samples per pixel")
            ->check(CLI::Range(1u, kMaxSamplesPerPixel)));
  app->add_option("--max-rounds", a.max_rounds, "Stop rule: stop after this many rounds (0 = all)");
  app->add_option("--time-budget", a.time_budget,
                  "Stop rule: seconds (0 = none; the image then depends on timing)");
  app->add_option("--target-noise", a.target_noise, "Stop rule: estimated noise RMS to reach (0 = none)");
  app->add_option("--priority", a.priority, "Job priority (higher first)");
  app->add_option("--name", a.name, "Job name (default: the scene's file name)");
  // Who traces the maps (docs/farm.md, "Photon maps traced once").
  app->add_option("--map-tracing", a.map_tracing,
                  "farm, photonmap: who traces the photon maps: auto (traced once in pieces by the workers "
                  "and built once by the coordinator when several tasks use a kd-tree map), local (each "
                  "worker traces the maps of its tasks), distributed (always traced once; kdtree only). "
                  "The image is the same")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "local", "distributed"}));
}

CameraSpec ChooseCamera(const SceneDescription& scene, const RenderArgs& a) {
  CameraSpec cam;
  if (!a.camera_name.empty()) {
    bool found = false;
    for (const CameraSpec& c : scene.cameras)
      if (c.name == a.camera_name) {
        cam = c;
        found = true;
      }
    if (!found) throw InputError("--camera: the scene has no camera named '" + a.camera_name + "'");
  } else if (!scene.cameras.empty()) {
    cam = scene.cameras.front();
  } else {
    cam = DefaultCamera(scene);
  }
  if (!a.eye.empty()) cam.eye = ParsePoint(a.eye, "--eye");
  if (!a.look_at.empty()) cam.look_at = ParsePoint(a.look_at, "--look-at");
  if (!a.up.empty()) cam.up = ParseVec3(a.up, "--up");
  if (a.fov != 0.0f) cam.vfov_degrees = a.fov;
  if (!a.res.empty()) ParseResolution(a.res, cam.width, cam.height);
  return cam;
}

PreparedJob PrepareJob(const RenderArgs& a) {
  PreparedJob p;
  p.scene = LoadScene(a.scene);
  for (const std::string& w : p.scene.warnings) spdlog::warn("scene: {}", w);
  p.bundle = CollectBundle(a.scene);
  v1::JobSpec& s = p.spec;
  s.set_name(a.name.empty() ? std::filesystem::path(a.scene).filename().string() : a.name);
  CameraToProto(ChooseCamera(p.scene, a), s.mutable_camera());

  RenderSettingsFromArgs(a, s.mutable_settings());
  // Validates (InputError naming the flag's field) and tells the user what `auto` becomes here;
  // the workers decide alike from the same scene.
  ResolveAndLog(SettingsFromProto(s.settings(), "settings"), p.scene);

  // --plan auto is the farm's default (docs/farm.md, "Choosing the plan": --workers, submit); --local-only
  // and a plain render keep multiple maps unless asked.
  const std::string plan = !a.plan.empty()                                ? a.plan
                           : (a.workers > 0 && !a.local_only) || a.submit ? "auto"
                                                                          : "multiple-maps";
  v1::Plan* pl = s.mutable_plan();
  if (plan == "auto") {
    if (!a.plan_flags_given.empty())
      throw InputError(
          a.plan_flags_given.front() +
          ": not used by --plan auto, which chooses the plan's shape (give --plan multiple-maps, "
          "skipping, maps-in-turn or hierarchical to set it)");
    pl->mutable_auto_plan()->set_workers(uint32_t(std::max(0, a.workers)));  // 0: the coordinator counts
    pl->mutable_auto_plan()->set_samples_per_pixel(a.spp);
  } else if (plan == "multiple-maps") {
    pl->mutable_multiple_maps()->set_maps(a.maps);
    pl->mutable_multiple_maps()->set_samples_per_pixel(a.spp);
    pl->mutable_multiple_maps()->set_tile_size(a.tile);
    pl->mutable_multiple_maps()->set_tail_tile_size(TailTileFor(a));
  } else if (plan == "maps-in-turn") {
    pl->mutable_maps_in_turn()->set_samples_per_pixel(a.spp);
    pl->mutable_maps_in_turn()->set_tile_size(a.tile);
  } else if (plan == "hierarchical") {
    v1::Hierarchical* h = pl->mutable_hierarchical();
    h->set_levels(a.levels);
    h->set_dims(a.dims);
    h->set_base_samples(a.base_samples);
    h->set_min_samples(a.min_samples);
    h->set_decay(a.decay);
    h->set_localize_threshold(a.localize_threshold);
    h->set_localize_contrast(a.localize_contrast);
    h->set_samples_per_pixel(a.spp);
    h->set_rows_per_task(a.tile);
    if (a.hier_part == "indirect") {
      h->set_part(v1::HIERARCHY_PART_INDIRECT);
      h->set_direct_samples_per_pixel(a.hier_direct_samples);
    }
  } else {
    pl->mutable_skipping()->set_stride(a.stride);
    pl->mutable_skipping()->set_rounds(a.rounds);
    pl->mutable_skipping()->set_samples_per_pixel(a.spp);
  }
  s.set_seed(a.seed);
  s.mutable_stop()->set_max_rounds(a.max_rounds);
  s.mutable_stop()->set_time_budget_seconds(a.time_budget);
  s.mutable_stop()->set_target_noise_rms(a.target_noise);
  s.set_priority(a.priority);
  if ((a.local_only || (a.workers == 0 && !a.submit)) && s.plan().has_auto_plan()) {
    // The coordinator's resolution, here: the local render runs the plan the farm would.
    const CameraSpec cam = CameraFromProto(s.camera(), "spec.camera");
    ResolveAutoPlan(&s, cam.width, cam.height, SceneNeedsCausticMap(p.scene) ? 1 : 0,
                    uint32_t(std::max(1, a.workers)), kMapsCanBeShipped, "spec");
    spdlog::info("plan auto: {}", s.plan().chosen_by_auto().reason());
  }
  return p;
}

}  // namespace pf
