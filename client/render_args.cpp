#include "client/render_args.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <regex>
#include <sstream>
#include <variant>

#include "common/core/error.h"
#include "common/core/real_text.h"
#include "common/photon/photon_tracer.h"
#include "common/plan/frame_tasks.h"
#include "common/plan/plan_choice.h"
#include "common/plan/plan_factory.h"
#include "common/plan/stop_targets.h"
#include "common/render/integrator_choice.h"
#include "common/render/integrator_factory.h"
#include "common/render/progressive_radius.h"
#include "common/render/render_settings_table.h"
#include "common/scene/camera_path.h"
#include "common/scene/manifest.h"
#include "common/scene/scene_loader.h"
#include "proto/convert.h"
#include "proto/limits.h"

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
  // An animation's many frames already end the job on small pieces of work (and a plan without
  // tail tiles can be requeued with more maps).
  if (!a.frames.empty()) return 0;
  const bool farm = (a.workers > 1 && !a.local_only) || a.submit;
  const uint32_t half = a.tile / 2;
  return farm && a.tile >= 32 && half % 16 == 0 ? half : 0;
}

// With `--integrator auto`: the photon map was asked for by a setting only it reads, or by a plan
// only it has (progressive; hierarchical with its indirect part apart).
bool PhotonMapAsked(const RenderArgs& a) {
  if (a.plan == "progressive" || (a.plan == "hierarchical" && a.hier_part == "indirect")) return true;
  JobRenderSettings path;
  path.integrator = IntegratorKind::kPath;
  for (const GivenSetting& g : SettingsGiven(a.settings))
    if (const RenderSetting* row = FindRenderSetting(g.name); row && !IntegratorReads(path, *row))
      return true;
  return false;
}

// An `integrator` row of --set, a settings file or the manifest: a named integrator, as
// --integrator is (the command line's over the manifest's).
std::optional<GivenSetting> IntegratorRowGiven(const RenderArgs& a) {
  std::optional<GivenSetting> found;
  for (const GivenSetting& g : a.settings.manifest)
    if (g.name == "integrator") found = g;
  for (const GivenSetting& g : SettingsGiven(a.settings))
    if (g.name == "integrator") found = g;
  return found;
}

// `--integrator auto` for this scene and camera (integrator_choice.h). The user's occlusion
// settings, on the command line, in a settings file or in the manifest, are theirs to keep: the
// per-site test and the camera path's are exclusive (render_settings_rules.h).
IntegratorChoice ChooseIntegratorFor(const SceneDescription& scene, const CameraSpec& camera,
                                     const RenderArgs& a) {
  // The manifest's rows first, so that the command line's win; only what sets the search radius.
  std::vector<GivenSetting> given = a.settings.manifest;
  const std::vector<GivenSetting> command_line = SettingsGiven(a.settings);
  given.insert(given.end(), command_line.begin(), command_line.end());
  JobRenderSettings radius_settings;
  for (const GivenSetting& g : given)
    if (g.name == "photons" || g.name == "k" || g.name == "progressive-radius") {
      const RenderSetting& row = *FindRenderSetting(g.name);
      row.set(radius_settings, ParseRenderSettingValue(row, g.text, g.source));
    }
  IntegratorEvidence e = SceneEvidence(scene, camera, radius_settings);
  e.photon_map_settings_given = PhotonMapAsked(a);
  for (const GivenSetting& g : given)
    e.occlusion_test_given |= g.name == "occlusion-test" || g.name == "site-occlusion-test";
  return ChooseIntegrator(e);
}

}  // namespace

std::string FormatVec(const Vec3& v) {
  return RealText(Vec3d(v));
}

std::string FormatVec(const Vec3d& v) {
  // A component that is a float (every camera of a scene around the origin) prints as the
  // shortest text of that float; others as the shortest text of the double (real_text.h).
  return RealText(v);
}

void ApplyManifestSettings(RenderArgs& a) {
  if (std::filesystem::path(a.scene).extension() != ".json") return;
  const SceneManifest manifest = LoadManifest(a.scene);
  for (const auto& [key, value] : manifest.settings) {
    const std::string text = std::holds_alternative<double>(value)
                                 ? fmt::format("{}", std::get<double>(value))
                                 : std::get<std::string>(value);
    const std::string source = a.scene + ": settings." + key;
    if (key == "spp") {
      // A plan's --spp means samples per map or per task (see --spp): only a plain render takes
      // the manifest's, which is a per-pixel count.
      const double v = std::holds_alternative<double>(value) ? std::get<double>(value) : -1;
      if (!(v >= 1 && v <= kMaxSamplesPerPixel) || v != std::floor(v))
        throw InputError(source + ": expected a whole number in 1.." + std::to_string(kMaxSamplesPerPixel) +
                         ", got " + text);
      const bool plain = a.plan.empty() && !a.local_only && a.workers == 0;
      if (!a.spp_given && plain) {
        a.spp = uint32_t(v);
        spdlog::info("spp = {} from the manifest's settings (--spp overrides)", a.spp);
      }
    } else if (FindRenderSetting(key)) {
      a.settings.manifest.push_back({key, text, source});
    }  // other keys are the scene's notes (e.g. expected_pixel_value)
  }
}

void AddSceneOptions(CLI::App* app, RenderArgs& a, bool all) {
  auto more = [all](CLI::Option* o) { return all ? o : o->group(""); };
  app->add_option("scene", a.scene, "Scene manifest (.json) or geometry file (.mgf, .obj)")->required();
  app->add_option("--integrator", a.integrator,
                  "auto (chosen from the scene and a pilot of shadow rays, logged), path (reference path "
                  "tracer) or photonmap (Wald 1999)")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "path", "photonmap"}));
  app->add_option("--spp", a.spp, "Samples per pixel (with --plan: per map or per task; see --help-all)")
      ->capture_default_str()
      ->check(CLI::Range(1u, kMaxSamplesPerPixel));
  more(app->add_option("--seed", a.seed,
                       "Seed: the same seed gives the same image on any thread or worker count")
           ->capture_default_str());
  app->add_option("--camera", a.camera_name, "Named camera of the manifest (default: its first)");
  app->add_option(
         "--frames", a.frames,
         "Animation: frames A-B (or all) of the scene's camera path (a manifest's camera_path, a glTF "
         "camera's animation), one job on a farm "
         "(pf submit, --workers N) sharing its photon maps; -o out.%04d.exr")
      ->check([](const std::string& v) {  // an empty value would silently render a still image
        return v.empty() ? std::string("expected FIRST-LAST, one frame number or all") : std::string();
      });
  more(app->add_option("--eye", a.eye, "Camera position X,Y,Z (overrides the manifest)"));
  more(app->add_option("--look-at", a.look_at, "Point the camera looks at X,Y,Z"));
  more(app->add_option("--up", a.up, "Up vector X,Y,Z (image right = forward x up)"));
  more(
      app->add_option("--fov", a.fov, "Vertical field of view in degrees")->check(CLI::Range(0.01f, 179.9f)));
  app->add_option("--res", a.res, "Resolution WxH, e.g. 640x480");
  AddSettingOptions(app, a.settings);
}

void CheckSettingArgs(const RenderArgs& a) {
  try {
    // Before the scene is loaded `auto` is judged by what was asked: photon-map settings make it the
    // photon map, and without them every setting given is one the path tracer reads too.
    const std::optional<GivenSetting> row = IntegratorRowGiven(a);
    SettingsFromArgs(a.settings, a.integrator != "auto" ? a.integrator
                                 : row                  ? row->text
                                 : PhotonMapAsked(a)    ? "photonmap"
                                                        : "path");
  } catch (const InputError& e) {
    throw CLI::ValidationError(e.what());
  }
  // The radius schedule is read only by a progressive plan's tasks (progressive_radius.h).
  if (a.plan != "progressive")
    for (const GivenSetting& g : SettingsGiven(a.settings))
      if (g.name.starts_with(kProgressiveSettingPrefix))
        throw CLI::ValidationError(g.source, "applies only with --plan progressive");
  // Who traces the maps is a farm setting; in one process they are traced here.
  if (!a.submit && a.workers == 0)
    for (const GivenSetting& g : SettingsGiven(a.settings))
      if (g.name == "map-tracing")
        throw CLI::ValidationError(g.source,
                                   "applies to farm renders only (--workers N); in one process the maps are "
                                   "traced by this process");
}

void RenderSettingsFromArgs(const RenderArgs& a, v1::RenderSettings* rs) {
  SettingsToProto(SettingsFromArgs(a.settings, a.integrator), rs);
}

JobRenderSettings ResolveAndLog(const JobRenderSettings& settings, const SceneDescription& scene) {
  std::vector<AutoChoice> choices;
  JobRenderSettings resolved = settings.Resolved(scene, &choices);
  for (const AutoChoice& c : choices) spdlog::info("auto {} = {}: {}", c.setting, c.value, c.reason);
  return resolved;
}

namespace {

// --plan's values: auto (plan_choice.h) and every plan of the registry (plan_factory.h).
std::vector<std::string> PlanNamesWithAuto() {
  std::vector<std::string> names = Plans().Names();
  names.insert(names.begin(), "auto");
  return names;
}

}  // namespace

void AddPlanOptions(CLI::App* app, RenderArgs& a, bool all) {
  auto more = [all](CLI::Option* o) { return all ? o : o->group(""); };
  const char* plan_help =
      "How the image is split into tasks (Wald 1999, 4.4): multiple-maps (--maps independent maps "
      "over --tile tiles, averaged), maps-in-turn (sample i from map i), skipping (per round a "
      "seeded pixel permutation, stride^2 tasks each with its own map), hierarchical (4.5: "
      "multilevel sampling, every sample of a pixel from its own map, --levels/--dims/--base-samples/"
      "--min-samples/--decay/--localize-*; --tile = rows per task), progressive (Knaus & Zwicker 2011: "
      "--passes independent maps of --photons photons, each estimating with every photon within a radius "
      "that shrinks from pass to pass, settings progressive-alpha/-radius; consistent), or auto (the default "
      "of --workers and "
      "`pf submit`; --local-only defaults to multiple-maps): the coordinator picks the plan, the number "
      "of "
      "maps and photons per map from the scene, the workers and the stop rule, with --photons the budget "
      "over all maps and --spp the samples per pixel over all maps (docs/farm.md, \"Choosing the plan\")";
  app->add_option(
         "--plan", a.plan,
         all ? plan_help
             : "auto, multiple-maps, maps-in-turn, skipping, hierarchical or progressive (Wald 1999, 4.4; "
               "--help-all tells more)")
      ->check(CLI::IsMember(PlanNamesWithAuto()));
  // Which plan-shape flags were given: --plan auto chooses them itself.
  auto shape = [&a, more](CLI::Option* o) {
    o->each([&a, name = o->get_name()](const std::string&) { a.plan_flags_given.push_back(name); });
    return more(o->capture_default_str());
  };
  shape(app->add_option("--maps", a.maps, "multiple-maps: number of independent maps"));
  shape(app->add_option("--passes", a.passes,
                        "progressive: passes (independent maps, each with its radius r_p)"));
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
  more(app->add_option("--max-rounds", a.max_rounds, "Stop rule: stop after this many rounds (0 = all)"));
  app->add_option("--time-budget", a.time_budget,
                  "Stop rule: seconds (0 = none; the image then depends on timing)");
  more(app->add_option("--target-noise", a.target_noise,
                       "Stop rule: estimated noise RMS to reach (0 = none)"));
  app->add_option("--target-error", a.target_error,
                  "Stop rule: estimated error RMS (noise and bias) to reach; progressive plan or path tracer")
      ->check(CLI::NonNegativeNumber);
  more(app->add_option("--priority", a.priority, "Job priority (higher first)"));
  more(app->add_option("--name", a.name, "Job name (default: the scene's file name)"));
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

namespace {

// --frames: the frames' cameras from the manifest's camera path, each `camera` (the resolution,
// and the up and field of view a key leaves out) moved along it (common/scene/camera_path.h).
void AddFrames(const SceneDescription& scene, const RenderArgs& a, const CameraSpec& camera, v1::JobSpec* s) {
  if (a.local_only || (a.workers == 0 && !a.submit))
    throw InputError("--frames: an animation renders on a farm (pf submit, or pf render --workers N)");
  if (!a.png.empty())
    throw InputError("--png: an animation is written as one EXR per frame, without previews");
  for (const auto& [value, flag] : {std::pair{&a.eye, "--eye"}, {&a.look_at, "--look-at"}, {&a.up, "--up"}})
    if (!value->empty())
      throw InputError(std::string(flag) + ": not with --frames (the camera path moves the camera)");
  if (a.fov != 0.0f) throw InputError("--fov: not with --frames (the camera path sets the field of view)");
  const CameraPath& path = scene.camera_path;
  if (path.keys.empty())
    throw InputError(
        "--frames: the scene has no camera path (a manifest's \"camera_path\", docs/scene-manifest.md, or an "
        "animated glTF camera, docs/gltf.md)");
  int first = path.first_frame(), last = path.last_frame();
  if (a.frames != "all") {
    // Digits only ("+3", " 3" and "3x" are not frame numbers), at most 6 of them (frame ≤ 999999).
    static const std::regex kRange(R"(([0-9]{1,6})(-([0-9]{1,6}))?)");
    std::smatch m;
    if (!std::regex_match(a.frames, m, kRange))
      throw InputError("--frames: '" + a.frames + "': expected FIRST-LAST, one frame number or all");
    first = std::stoi(m[1].str());
    last = m[3].matched ? std::stoi(m[3].str()) : first;
    if (first > last || first < path.first_frame() || last > path.last_frame())
      throw InputError("--frames: " + a.frames + " is not within the camera path's frames " +
                       std::to_string(path.first_frame()) + "-" + std::to_string(path.last_frame()));
  }
  if (size_t(last - first + 1) > limits::kMaxFrames)
    throw InputError("--frames: " + std::to_string(last - first + 1) + " frames exceed the limit of " +
                     std::to_string(limits::kMaxFrames) + " per job; submit the range in parts");
  v1::Animation* anim = s->mutable_animation();
  anim->set_first_frame(uint32_t(first));
  for (const CameraSpec& c : CamerasOfFrames(path, camera, first, last))
    CameraToProto(c, anim->add_cameras());
  // spec.camera is the first frame's: the integrator's choice and the resolution read it.
  *s->mutable_camera() = anim->cameras(0);
  spdlog::info("animation: frames {}-{} ({}) along the camera path", first, last, last - first + 1);
}

}  // namespace

PreparedJob PrepareJob(const RenderArgs& args) {
  PreparedJob p;
  p.scene = LoadScene(args.scene);
  for (const std::string& w : p.scene.warnings) spdlog::warn("scene: {}", w);
  p.bundle = CollectBundle(args.scene);
  v1::JobSpec& s = p.spec;
  s.set_name(args.name.empty() ? std::filesystem::path(args.scene).filename().string() : args.name);
  CameraSpec camera = ChooseCamera(p.scene, args);
  CameraToProto(camera, s.mutable_camera());
  if (!args.frames.empty()) {
    AddFrames(p.scene, args, camera, &s);
    camera = CameraFromProto(s.camera(), "spec.camera");
  }
  // `--integrator auto`, decided here where the scene is loaded: the job carries the concrete
  // integrator, and the choice and its reason ride along in spec.auto_settings (the image header's
  // auto.* keys).
  RenderArgs a = args;
  if (a.integrator == "auto") {
    if (const std::optional<GivenSetting> row = IntegratorRowGiven(a)) {
      a.integrator = row->text;
      spdlog::info("integrator {} from {}", row->text, row->source);
    }
  }
  if (a.integrator == "auto") {
    const IntegratorChoice chosen = ChooseIntegratorFor(p.scene, camera, a);
    a.integrator = chosen.integrator == IntegratorKind::kPath ? "path" : "photonmap";
    if (chosen.occlusion_test) a.settings.long_flags.push_back({"occlusion-test", "true", "integrator auto"});
    for (const AutoChoice& c : chosen.choices) {
      spdlog::info("auto {} = {}: {}", c.setting, c.value, c.reason);
      AutoChoiceToProto(c, s.add_auto_settings());
    }
  }

  RenderSettingsFromArgs(a, s.mutable_settings());
  // Validates (InputError naming the flag's field) and tells the user what `auto` becomes here;
  // the workers decide alike from the same scene.
  ResolveAndLog(SettingsFromProto(s.settings(), "settings"), p.scene);

  // --plan auto is the farm's default (docs/farm.md, "Choosing the plan": --workers, submit); --local-only
  // and a plain render keep multiple maps unless asked.
  const bool farm_default = (a.workers > 0 && !a.local_only) || a.submit;
  const bool budget = a.time_budget > 0 || a.target_noise > 0 || a.target_error > 0;
  std::string plan = !a.plan.empty() ? a.plan : farm_default ? "auto" : "multiple-maps";
  // An animation's maps are shared by all its frames (common/plan/frame_tasks.h): auto may choose
  // skipping, whose every task traces its own map, so the default is multiple maps.
  if (!a.frames.empty() && a.plan.empty()) {
    plan = a.target_error > 0 && a.integrator == "photonmap" ? "progressive" : "multiple-maps";
    spdlog::info("plan {}: chosen for an animation (every frame shares its maps; --plan sets another)", plan);
  }
  if (!a.frames.empty() && plan == "auto")
    throw InputError(
        "--plan auto: not with --frames (it may choose skipping, which shares no map between "
        "frames); give multiple-maps, maps-in-turn or progressive");
  if (!a.frames.empty())
    if (const std::string problem = FramesPlanProblem(PlanSpec{.kind = Plans().Find(plan, "--plan").kind});
        !problem.empty())
      throw InputError("--plan " + plan + ": not with --frames: " + problem);
  // A render in this process with a budget and no plan (docs/renderer.md, "Budgets"): the
  // consistent plan of its integrator, open-ended, so that the budget decides how far it gets —
  // the path tracer's independent sample sets, the photon map's progressive passes (a fixed-size
  // map would stop improving at its bias however long it ran).
  uint32_t maps = a.maps, passes = a.passes;
  const auto given = [&a](const char* flag) {
    return std::find(a.plan_flags_given.begin(), a.plan_flags_given.end(), flag) != a.plan_flags_given.end();
  };
  // A target error is judged only for the progressive plan (stop_targets.h): the photon map's
  // jobs with one and no --plan get that plan on the farm too, where auto would choose another.
  if (a.target_error > 0 && a.plan.empty() && farm_default && a.integrator == "photonmap" &&
      a.frames.empty()) {
    plan = "progressive";
    spdlog::info("plan progressive: chosen for --target-error (the plan whose bias is estimated)");
  }
  uint32_t spp = a.spp;
  if (budget && a.plan.empty() && !farm_default) {
    plan = a.integrator == "photonmap" ? "progressive" : "multiple-maps";
    if (plan == "multiple-maps") maps = kOpenEndedPasses;
    spdlog::info(
        "plan {}: chosen for the budget ({}), until the budget ends it", plan,
        plan == "progressive" ? "the photon map's consistent plan" : "the path tracer's sample sets");
    if (plan == "multiple-maps" && given("--passes"))
      throw InputError("--passes: the budget runs the path tracer's sample sets here (" + a.integrator +
                       " integrator), which have no passes; give --plan progressive "
                       "with --integrator photonmap, or leave --passes out");
    if (plan == "progressive" && !a.spp_given) {
      spp = kBudgetPassSamples;
      spdlog::info("progressive: {} samples per pixel per pass (--spp sets them)", spp);
    }
  }
  if (budget && plan == "progressive" && !given("--passes")) {
    passes = kOpenEndedPasses;
    if (s.animation().cameras_size() > 0) {
      // Every pass is a task per tile and frame: as many passes as a job's tasks allow.
      const uint64_t side = a.tile == 0 ? 0 : a.tile;
      const uint64_t tiles = side == 0 ? 1
                                       : ((uint64_t(camera.width) + side - 1) / side) *
                                             ((uint64_t(camera.height) + side - 1) / side);
      const uint64_t per_pass = tiles * uint64_t(s.animation().cameras_size());
      passes = uint32_t(std::clamp<uint64_t>(limits::kMaxTasksPerJob / per_pass, 1, kOpenEndedPasses));
    }
    spdlog::info("progressive: up to {} passes, until the budget ends it (--passes sets the count)", passes);
  }
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
    pl->mutable_multiple_maps()->set_maps(maps);
    pl->mutable_multiple_maps()->set_samples_per_pixel(a.spp);
    pl->mutable_multiple_maps()->set_tile_size(a.tile);
    pl->mutable_multiple_maps()->set_tail_tile_size(TailTileFor(a));
  } else if (plan == "progressive") {
    pl->mutable_progressive()->set_passes(passes);
    pl->mutable_progressive()->set_samples_per_pixel(spp);
    pl->mutable_progressive()->set_tile_size(a.tile);
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
  s.mutable_stop()->set_target_error_rms(a.target_error);
  s.set_priority(a.priority);
  for (const std::string& id : a.after) s.add_after(id);
  if ((a.local_only || (a.workers == 0 && !a.submit)) && s.plan().has_auto_plan()) {
    // The coordinator's resolution, here: the local render runs the plan the farm would.
    const CameraSpec cam = CameraFromProto(s.camera(), "spec.camera");
    ResolveAutoPlan(&s, cam.width, cam.height, SceneNeedsCausticMap(p.scene) ? 1 : 0,
                    uint32_t(std::max(1, a.workers)), kMapsCanBeShipped, "spec");
    spdlog::info("plan auto: {}", s.plan().chosen_by_auto().reason());
  }
  // The progressive schedule's α, written even at its default: a coordinator of an older build
  // reads an unset one as its own default (docs/farm.md, "Upgrades").
  if (s.plan().has_progressive())
    WriteProgressiveAlpha(SettingsFromProto(s.settings(), "settings"), s.mutable_settings());
  return p;
}

}  // namespace pf
