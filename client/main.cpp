// pf — the photonfarm command-line client.
//
//   pf render SCENE [options]   render a scene in this process (the farm adds --workers N)
//   pf diff A.exr REF.exr       compare two images: RMSE, relative MSE, max error
//   pf info SCENE               what a scene contains: triangles, lights, materials, cameras
//
// Exit codes (documented in --help): 0 success, 1 runtime failure (I/O, Embree), 2 usage
// error, 3 invalid input (scene or manifest, reported as file:line: reason), 130 interrupted.
#include <CLI/CLI.hpp>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "common/accel/embree_scene.h"
#include "common/core/error.h"
#include "common/image/exr_io.h"
#include "common/image/image_diff.h"
#include "common/image/png_io.h"
#include "common/render/camera.h"
#include "common/render/light_sampler.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/renderer.h"
#include "common/scene/scene_loader.h"

namespace pf {
namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;
constexpr int kExitBadInput = 3;

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

// A progress bar on stderr while `done` counts up to `total`; plain lines when not a terminal.
class ProgressBar {
 public:
  ProgressBar(const std::atomic<uint64_t>& done, uint64_t total, bool enabled)
      : done_(done), total_(total), enabled_(enabled), tty_(isatty(fileno(stderr))) {
    if (enabled_) thread_ = std::thread([this] { Run(); });
  }
  ~ProgressBar() { Finish(); }
  void Finish() {
    if (!thread_.joinable()) return;
    stop_ = true;
    thread_.join();
    Draw(true);
    if (tty_) std::fputc('\n', stderr);
  }

 private:
  void Run() {
    while (!stop_) {
      std::this_thread::sleep_for(std::chrono::milliseconds(tty_ ? 200 : 100));
      Draw(false);
    }
  }
  void Draw(bool final) {
    const uint64_t done = std::min(done_.load(), total_);
    const double frac = total_ ? double(done) / double(total_) : 1.0;
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (tty_) {
      constexpr int kWidth = 40;
      const int filled = int(frac * kWidth);
      std::string bar(size_t(filled), '#');
      bar.resize(kWidth, '.');
      const double eta = frac > 0 ? elapsed * (1.0 - frac) / frac : 0.0;
      std::fprintf(stderr, "\r[%s] %5.1f%%  %6.1fs elapsed  ETA %6.1fs", bar.c_str(), 100.0 * frac, elapsed, eta);
      std::fflush(stderr);
    } else {
      const int decile = int(frac * 10.0);
      if (decile > last_decile_ || final) {
        last_decile_ = decile;
        if (!final || decile < 10) std::fprintf(stderr, "progress %3d%% after %.1fs\n", decile * 10, elapsed);
      }
    }
  }
  const std::atomic<uint64_t>& done_;
  uint64_t total_;
  bool enabled_, tty_;
  std::atomic<bool> stop_{false};
  int last_decile_ = 0;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::thread thread_;
};

struct RenderArgs {
  std::string scene;
  std::string integrator = "path";
  uint32_t spp = 16;
  std::string output;
  std::string png;
  bool no_png = false;
  int threads = 0;
  uint64_t seed = 1;
  std::string camera_name;
  std::string eye, look_at, up, res;
  float fov = 0.0f;
  bool quiet = false;
  // Photon map (--integrator photonmap).
  uint64_t photons = 200000;
  int k = 100;
  std::string map = "kdtree";
  std::string kd_split = "cycle";
  std::string caustic = "auto";
  float caustic_radius = 0.0f;
  int glossy_depth = 1;
  std::string direction_test = "in-query";
};

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

std::string FormatVec(const Vec3& v) { return fmt::format("{},{},{}", v.x, v.y, v.z); }

int RunRender(const RenderArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  const SceneDescription scene = LoadScene(a.scene);
  const CameraSpec spec = ChooseCamera(scene, a);
  const Camera camera(spec);
  spdlog::info("scene {}: {} triangles, {} emitting, {} lights, {} materials", a.scene, scene.NumTriangles(),
               scene.NumEmissiveTriangles(), scene.num_lights, scene.materials.size());
  const EmbreeScene accel(scene);
  const LightSampler lights(accel);
  if (lights.empty()) spdlog::warn("the scene has no emitters: the image will be black");
  const double load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::unique_ptr<Integrator> integrator;
  PhotonMaps maps;
  if (a.integrator == "path") {
    integrator = std::make_unique<PathTracer>(accel, lights);
  } else if (a.integrator == "photonmap") {
    PhotonMapsOptions mo;
    mo.tracing.photons = a.photons;
    mo.tracing.map_seed = HashKey(a.seed, 0x6d6170 /* "map" */);
    mo.tracing.threads = a.threads;
    mo.kind = a.map == "grid" ? PhotonMapKind::kGrid : PhotonMapKind::kKdTree;
    mo.structure.kd_split_rule = a.kd_split == "widest" ? KdSplitRule::kWidestExtent : KdSplitRule::kLevelCycle;
    mo.structure.grid.expected_k = a.k;
    mo.caustic = a.caustic == "on" ? CausticMapMode::kOn : a.caustic == "off" ? CausticMapMode::kOff : CausticMapMode::kAuto;
    maps = PhotonMaps::Build(accel, lights, mo);
    PhotonMapIntegratorOptions io;
    io.global.k = a.k;
    io.caustic = DefaultCausticOptions(a.k, accel.bounds());
    if (a.caustic_radius > 0) io.caustic.max_radius = a.caustic_radius;
    const FeasibilityTest test = a.direction_test == "none"    ? FeasibilityTest::kNone
                                 : a.direction_test == "after" ? FeasibilityTest::kAfterQuery
                                                               : FeasibilityTest::kInQuery;
    io.global.direction_test = io.caustic.direction_test = test;
    io.glossy_depth = a.glossy_depth;
    integrator = std::make_unique<PhotonMapIntegrator>(accel, maps, io);
  } else {
    throw InputError("--integrator: unknown integrator '" + a.integrator + "' (available: path, photonmap)");
  }

  RenderOptions options;
  options.spp = a.spp;
  options.seed = a.seed;
  options.threads = a.threads;
  std::atomic<uint64_t> progress{0};
  RenderStats stats;
  Image image;
  {
    ProgressBar bar(progress, uint64_t(spec.width) * spec.height, !a.quiet);
    image = RenderImage(*integrator, camera, options, &stats, &progress);
  }

  const std::string output = a.output.empty() ? std::filesystem::path(a.scene).stem().string() + ".exr" : a.output;
  ImageMetadata meta = {
      {"scene", a.scene},
      {"integrator", integrator->name()},
      {"spp", std::to_string(a.spp)},
      {"seed", std::to_string(a.seed)},
      {"camera.eye", FormatVec(spec.eye)},
      {"camera.look_at", FormatVec(spec.look_at)},
      {"camera.up", FormatVec(spec.up)},
      {"camera.vfov_degrees", fmt::format("{}", spec.vfov_degrees)},
      {"render_seconds", fmt::format("{:.3f}", stats.seconds)},
      {"rays", std::to_string(stats.counters.rays + stats.counters.shadow_rays)},
      {"nonfinite_samples", std::to_string(stats.nonfinite_samples)},
  };
  if (maps.global) {
    meta["photons.emitted"] = std::to_string(maps.stats.emitted);
    meta["photons.global"] = std::to_string(maps.stats.stored_global);
    meta["photons.caustic"] = std::to_string(maps.stats.stored_caustic);
    meta["photons.k"] = std::to_string(a.k);
    meta["photons.map"] = a.map;
    meta["photons.trace_seconds"] = fmt::format("{:.3f}", maps.stats.trace_seconds);
    meta["photons.build_seconds"] = fmt::format("{:.3f}", maps.stats.build_seconds);
  }
  WriteExr(output, image, meta);
  std::string png = a.png;
  if (png.empty() && !a.no_png) png = std::filesystem::path(output).replace_extension(".png").string();
  if (!png.empty()) WritePngPreview(png, image, PreviewOptions{.auto_exposure = true});

  const uint64_t rays = stats.counters.rays + stats.counters.shadow_rays;
  if (stats.nonfinite_samples > 0)
    spdlog::warn("{} samples were NaN/Inf and were dropped", stats.nonfinite_samples);
  std::printf("rendered %dx%d, %u spp, %s in %.2f s (+%.2f s load): %.2f M rays/s, %.2f M samples/s -> %s\n",
              spec.width, spec.height, a.spp, integrator->name(), stats.seconds, load_seconds,
              rays / stats.seconds * 1e-6, stats.samples / stats.seconds * 1e-6, output.c_str());
  return kExitOk;
}

int RunDiff(const std::string& a_path, const std::string& ref_path, const std::string& error_image,
            double error_scale, bool json) {
  const Image a = ReadExr(a_path);
  const Image ref = ReadExr(ref_path);
  const ImageDiffStats d = CompareImages(a, ref);
  if (json) {
    nlohmann::json j = {{"image", a_path},        {"reference", ref_path},     {"rmse", d.rmse},
                        {"relative_mse", d.relative_mse}, {"max_abs_error", d.max_abs_error},
                        {"max_x", d.max_x},       {"max_y", d.max_y},          {"mean", d.mean_a},
                        {"reference_mean", d.mean_b}, {"pixels", d.pixels}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("RMSE %.6g  relative MSE %.6g  max error %.6g at (%d,%d)  mean %.6g vs %.6g\n", d.rmse,
                d.relative_mse, d.max_abs_error, d.max_x, d.max_y, d.mean_a, d.mean_b);
  }
  if (!error_image.empty()) {
    const Image err = FalseColourError(a, ref, error_scale > 0 ? error_scale : d.max_abs_error);
    if (std::filesystem::path(error_image).extension() == ".exr")
      WriteExr(error_image, err);
    else
      WritePngPreview(error_image, err);
  }
  return kExitOk;
}

// Weighted average of images rendered with different seeds, weights = their spp (EXR metadata
// "spp"; 1 if absent). Prints the RMSE between the first two inputs halved — an estimate of the
// noise left in the average of two equal-spp halves.
int RunMerge(const std::vector<std::string>& inputs, const std::string& output) {
  Image sum;
  double total_weight = 0;
  double seconds = 0;
  std::vector<Image> first_two;
  std::vector<std::string> seeds;
  for (const std::string& path : inputs) {
    ImageMetadata meta;
    const Image img = ReadExr(path, &meta);
    if (sum.size() == 0) sum = Image(img.width(), img.height());
    if (img.width() != sum.width() || img.height() != sum.height())
      throw InputError(path + ": size " + std::to_string(img.width()) + "x" + std::to_string(img.height()) +
                       " differs from the first input");
    const double w = meta.count("spp") ? std::stod(meta["spp"]) : 1.0;
    if (meta.count("render_seconds")) seconds += std::stod(meta["render_seconds"]);
    if (meta.count("seed")) seeds.push_back(meta["seed"]);
    for (size_t i = 0; i < img.size(); ++i) sum[i] += img[i] * float(w);
    total_weight += w;
    if (first_two.size() < 2) first_two.push_back(img);
  }
  for (Rgb& c : sum.pixels()) c *= float(1.0 / total_weight);
  ImageMetadata meta = {{"spp", fmt::format("{}", total_weight)},
                        {"render_seconds", fmt::format("{:.1f}", seconds)},
                        {"merged_from", fmt::format("{}", fmt::join(inputs, ","))},
                        {"seeds", fmt::format("{}", fmt::join(seeds, ","))}};
  if (first_two.size() == 2) {
    const double noise = CompareImages(first_two[0], first_two[1]).rmse / 2.0;
    meta["estimated_noise_rmse"] = fmt::format("{:.6g}", noise);
    std::printf("estimated remaining noise (RMSE of the two halves / 2): %.6g\n", noise);
  }
  WriteExr(output, sum, meta, ExrCompression::kPiz);
  std::printf("merged %zu images, %g spp in all -> %s\n", inputs.size(), total_weight, output.c_str());
  return kExitOk;
}

int RunInfo(const std::string& path) {
  const SceneDescription scene = LoadScene(path);
  const Bounds3 b = scene.ComputeBounds();
  std::printf("scene       %s\ntriangles   %zu\nemitting    %zu triangles in %u lights\nmaterials   %zu\n",
              path.c_str(), scene.NumTriangles(), scene.NumEmissiveTriangles(), scene.num_lights,
              scene.materials.size());
  std::printf("bounds      (%g, %g, %g) .. (%g, %g, %g)\n", b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y, b.hi.z);
  for (const CameraSpec& c : scene.cameras)
    std::printf("camera      %s: eye %s look-at %s up %s fov %g res %dx%d\n", c.name.c_str(),
                FormatVec(c.eye).c_str(), FormatVec(c.look_at).c_str(), FormatVec(c.up).c_str(),
                c.vfov_degrees, c.width, c.height);
  std::printf("warnings    %zu\n", scene.warnings.size());
  for (const std::string& w : scene.warnings) std::printf("  %s\n", w.c_str());
  return kExitOk;
}

}  // namespace
}  // namespace pf

int main(int argc, char** argv) {
  using namespace pf;
  CLI::App app{
      "pf — photonfarm, photorealistic rendering with the photon map (Wald 1999).\n\n"
      "Examples:\n"
      "  pf render scenes/cornell-box/cornell-box.json --spp 256 -o cornell.exr\n"
      "  pf render scenes/office3/office.mgf --eye 1,1.5,2 --look-at 3,1,4 --fov 60 --res 640x480\n"
      "  pf diff cornell.exr scenes/cornell-box/reference.exr --error-image err.png\n"
      "  pf info scenes/scene8/scene8.json\n\n"
      "Exit codes: 0 ok, 1 runtime failure (I/O, Embree), 2 usage error, 3 invalid input\n"
      "(scene/manifest errors are reported as file:line: reason)."};
  app.require_subcommand(1);
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")->capture_default_str();

  RenderArgs ra;
  CLI::App* render = app.add_subcommand("render", "Render a scene (.json manifest, .mgf or .obj) to EXR + PNG");
  render->add_option("scene", ra.scene, "Scene manifest (.json) or geometry file (.mgf, .obj)")->required();
  render->add_option("--integrator", ra.integrator,
                     "path = reference path tracer (NEE + MIS + RR); photonmap = standalone photon-map "
                     "estimate in a distribution ray tracer (Wald 1999, 2.5)")
      ->capture_default_str()
      ->check(CLI::IsMember({"path", "photonmap"}));
  render->add_option("--spp", ra.spp, "Samples per pixel")->capture_default_str()->check(CLI::Range(1u, 1u << 20));
  render->add_option("-o,--output", ra.output, "Output EXR (float32 RGB; default: <scene>.exr)");
  render->add_option("--png", ra.png, "PNG preview path (default: output with .png)");
  render->add_flag("--no-png", ra.no_png, "Do not write a PNG preview");
  render->add_option("--threads", ra.threads, "Threads (0 = all cores)")->capture_default_str()->check(CLI::Range(0, 1024));
  render->add_option("--seed", ra.seed, "Seed: the same seed gives the same image on any thread count")
      ->capture_default_str();
  render->add_option("--camera", ra.camera_name, "Named camera of the manifest (default: its first)");
  render->add_option("--eye", ra.eye, "Camera position X,Y,Z (overrides the manifest)");
  render->add_option("--look-at", ra.look_at, "Point the camera looks at X,Y,Z");
  render->add_option("--up", ra.up, "Up vector X,Y,Z (image right = forward x up)");
  render->add_option("--fov", ra.fov, "Vertical field of view in degrees")->check(CLI::Range(0.01f, 179.9f));
  render->add_option("--res", ra.res, "Resolution WxH, e.g. 640x480");
  render->add_flag("-q,--quiet", ra.quiet, "No progress bar");
  render->add_option("--photons", ra.photons, "photonmap: photons emitted per map")
      ->capture_default_str()
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 31));
  render->add_option("--k", ra.k, "photonmap: nearest photons per radiance estimate")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  render->add_option("--map", ra.map, "photonmap: kdtree (left-balanced, 2.3) or grid (2.4)")
      ->capture_default_str()
      ->check(CLI::IsMember({"kdtree", "grid"}));
  render->add_option("--kd-split", ra.kd_split, "kdtree split axis: cycle (level % 3) or widest (extent)")
      ->capture_default_str()
      ->check(CLI::IsMember({"cycle", "widest"}));
  render->add_option("--caustic-map", ra.caustic,
                     "auto = only when the scene has specular/glossy surfaces; on; off")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "on", "off"}));
  render->add_option("--caustic-radius", ra.caustic_radius,
                     "photonmap: max caustic search radius (default 1% of the scene diagonal)");
  render->add_option("--glossy-depth", ra.glossy_depth,
                     "photonmap: glossy bounces followed before the map estimates the glossy lobe")
      ->capture_default_str()
      ->check(CLI::Range(0, 64));
  render->add_option("--direction-test", ra.direction_test,
                     "photonmap: photon direction vs normal test (4.1): in-query, after, none")
      ->capture_default_str()
      ->check(CLI::IsMember({"in-query", "after", "none"}));

  std::string diff_a, diff_ref, diff_err;
  double diff_scale = 0;
  bool diff_json = false;
  CLI::App* diff = app.add_subcommand("diff", "Compare an image with a reference: RMSE, relative MSE, max error");
  diff->add_option("image", diff_a, "Image to judge (EXR)")->required()->check(CLI::ExistingFile);
  diff->add_option("reference", diff_ref, "Reference (EXR)")->required()->check(CLI::ExistingFile);
  diff->add_option("--error-image", diff_err, "Write a false-colour error image (.png or .exr)");
  diff->add_option("--error-scale", diff_scale, "Error mapped to the top of the colour ramp (default: max)");
  diff->add_flag("--json", diff_json, "Print JSON instead of a line");

  std::vector<std::string> merge_inputs;
  std::string merge_output;
  CLI::App* merge = app.add_subcommand("merge", "Average EXRs rendered with different seeds, weighted by their spp");
  merge->add_option("inputs", merge_inputs, "EXR files")->required()->check(CLI::ExistingFile);
  merge->add_option("-o,--output", merge_output, "Output EXR (PIZ-compressed)")->required();

  std::string info_scene;
  CLI::App* info = app.add_subcommand("info", "Print what a scene contains (counts, bounds, cameras, warnings)");
  info->add_option("scene", info_scene, "Scene manifest or geometry file")->required();

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? kExitOk : kExitUsage;
  }
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
  try {
    if (*render) return RunRender(ra);
    if (*diff) return RunDiff(diff_a, diff_ref, diff_err, diff_scale, diff_json);
    if (*info) return RunInfo(info_scene);
    if (*merge) return RunMerge(merge_inputs, merge_output);
  } catch (const InputError& e) {
    spdlog::error("{}", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kExitFailure;
  }
  return kExitUsage;
}
