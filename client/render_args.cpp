#include "client/render_args.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <sstream>

#include "common/core/error.h"
#include "common/scene/scene_loader.h"
#include "proto/convert.h"

namespace pf {
namespace v1 = photonfarm::v1;

namespace {

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
      width > 16384 || height > 16384)
    throw InputError("--res: expected WxH with 1..16384 each, got '" + text + "'");
}

}  // namespace

std::string FormatVec(const Vec3& v) { return fmt::format("{},{},{}", v.x, v.y, v.z); }

void AddSceneOptions(CLI::App* app, RenderArgs& a) {
  app->add_option("scene", a.scene, "Scene manifest (.json) or geometry file (.mgf, .obj)")->required();
  app->add_option("--integrator", a.integrator,
                  "path = reference path tracer (NEE + MIS + RR); photonmap = standalone photon-map "
                  "estimate in a distribution ray tracer (Wald 1999, 2.5)")
      ->capture_default_str()
      ->check(CLI::IsMember({"path", "photonmap"}));
  app->add_option("--spp", a.spp,
                  "Samples per pixel (with --plan: per map for multiple-maps, = number of maps for "
                  "maps-in-turn, per task and pixel for skipping)")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1u << 20));
  app->add_option("--seed", a.seed, "Seed: the same seed gives the same image on any thread or worker count")
      ->capture_default_str();
  app->add_option("--camera", a.camera_name, "Named camera of the manifest (default: its first)");
  app->add_option("--eye", a.eye, "Camera position X,Y,Z (overrides the manifest)");
  app->add_option("--look-at", a.look_at, "Point the camera looks at X,Y,Z");
  app->add_option("--up", a.up, "Up vector X,Y,Z (image right = forward x up)");
  app->add_option("--fov", a.fov, "Vertical field of view in degrees")->check(CLI::Range(0.01f, 179.9f));
  app->add_option("--res", a.res, "Resolution WxH, e.g. 640x480");
  app->add_option("--photons", a.photons, "photonmap: photons emitted per map")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 31));
  app->add_option("--k", a.k, "photonmap: nearest photons per radiance estimate")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app->add_option("--map", a.map, "photonmap: kdtree (left-balanced, 2.3) or grid (2.4)")
      ->capture_default_str()
      ->check(CLI::IsMember({"kdtree", "grid"}));
  app->add_option("--kd-split", a.kd_split,
                  "kdtree split axis: cycle (level % 3) or widest (extent); plans and the farm use cycle")
      ->capture_default_str()
      ->check(CLI::IsMember({"cycle", "widest"}));
  app->add_option("--caustic-map", a.caustic, "auto = only when the scene has specular/glossy surfaces; on; off")
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
}

void AddPlanOptions(CLI::App* app, RenderArgs& a) {
  app->add_option("--plan", a.plan,
                  "How the image is split into tasks (Wald 1999, 4.4): multiple-maps (--maps independent maps "
                  "over --tile tiles, averaged), maps-in-turn (sample i from map i), skipping (per round a "
                  "seeded pixel permutation, stride^2 tasks each with its own map)")
      ->check(CLI::IsMember({"multiple-maps", "maps-in-turn", "skipping"}));
  app->add_option("--maps", a.maps, "multiple-maps: number of independent maps")->capture_default_str();
  app->add_option("--stride", a.stride, "skipping: S (S^2 tasks per round)")->capture_default_str();
  app->add_option("--rounds", a.rounds, "skipping: rounds")->capture_default_str();
  app->add_option("--tile", a.tile, "multiple-maps, maps-in-turn: tile side in pixels (0 = whole image)")
      ->capture_default_str();
  app->add_option("--max-rounds", a.max_rounds, "Stop rule: stop after this many rounds (0 = all)");
  app->add_option("--time-budget", a.time_budget, "Stop rule: seconds (0 = none; the image then depends on timing)");
  app->add_option("--target-noise", a.target_noise, "Stop rule: estimated noise RMS to reach (0 = none)");
  app->add_option("--priority", a.priority, "Job priority (higher first)");
  app->add_option("--name", a.name, "Job name (default: the scene's file name)");
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
  if (!a.eye.empty()) cam.eye = ParseVec3(a.eye, "--eye");
  if (!a.look_at.empty()) cam.look_at = ParseVec3(a.look_at, "--look-at");
  if (!a.up.empty()) cam.up = ParseVec3(a.up, "--up");
  if (a.fov != 0.0f) cam.vfov_degrees = a.fov;
  if (!a.res.empty()) ParseResolution(a.res, cam.width, cam.height);
  return cam;
}

PreparedJob PrepareJob(const RenderArgs& a) {
  PreparedJob p;
  p.scene = LoadScene(a.scene);
  p.bundle = CollectBundle(a.scene);
  v1::JobSpec& s = p.spec;
  s.set_name(a.name.empty() ? std::filesystem::path(a.scene).filename().string() : a.name);
  CameraToProto(ChooseCamera(p.scene, a), s.mutable_camera());

  v1::RenderSettings* rs = s.mutable_settings();
  if (a.integrator == "path") {
    rs->set_integrator(v1::INTEGRATOR_PATH);
  } else {
    rs->set_integrator(v1::INTEGRATOR_PHOTONMAP);
    v1::PhotonMapSettings* pm = rs->mutable_photon_map();
    pm->set_photons(a.photons);
    pm->set_k(uint32_t(a.k));
    pm->set_structure(a.map == "grid" ? v1::MAP_STRUCTURE_GRID : v1::MAP_STRUCTURE_KDTREE);
    pm->set_caustic(a.caustic == "on" ? v1::CAUSTIC_MODE_ON : a.caustic == "off" ? v1::CAUSTIC_MODE_OFF : v1::CAUSTIC_MODE_AUTO);
    pm->set_caustic_radius(a.caustic_radius);
    pm->set_glossy_depth(uint32_t(a.glossy_depth));
    pm->set_direction_test(a.direction_test == "none"    ? v1::DIRECTION_TEST_NONE
                           : a.direction_test == "after" ? v1::DIRECTION_TEST_AFTER_QUERY
                                                         : v1::DIRECTION_TEST_IN_QUERY);
    if (a.kd_split != "cycle") spdlog::warn("--kd-split {}: plans and the farm always use 'cycle'", a.kd_split);
  }

  const std::string plan = a.plan.empty() ? "multiple-maps" : a.plan;
  v1::Plan* pl = s.mutable_plan();
  if (plan == "multiple-maps") {
    pl->mutable_multiple_maps()->set_maps(a.maps);
    pl->mutable_multiple_maps()->set_samples_per_pixel(a.spp);
    pl->mutable_multiple_maps()->set_tile_size(a.tile);
  } else if (plan == "maps-in-turn") {
    pl->mutable_maps_in_turn()->set_samples_per_pixel(a.spp);
    pl->mutable_maps_in_turn()->set_tile_size(a.tile);
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
  return p;
}

}  // namespace pf
