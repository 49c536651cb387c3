// pf's in-process commands: render (classic and --local-only plans), diff, merge, info.
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <unistd.h>
#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "client/commands.h"
#include "client/progress.h"
#include "common/accel/embree_scene.h"
#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/core/real_text.h"
#include "common/image/exr_io.h"
#include "common/image/image_diff.h"
#include "common/image/png_io.h"
#include "common/lights/light_sampler.h"
#include "common/plan/hierarchical.h"
#include "common/plan/render_header.h"
#include "common/plan/task_executor.h"
#include "common/render/emitter_coverage.h"
#include "common/render/integrator_factory.h"
#include "common/render/path_tracer.h"
#include "common/render/photon_map_integrator.h"
#include "common/render/progressive_radius.h"
#include "common/render/render_settings_text.h"
#include "common/render/renderer.h"
#include "common/scene/scene_bundle.h"
#include "common/scene/scene_loader.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "proto/limits.h"

namespace pf {

void CheckWritable(const std::string& path, const char* what) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw SystemError(std::string(what) + " " + path + ": the folder " + dir.string() + " does not exist");
  if (fs::is_directory(p, ec)) throw SystemError(std::string(what) + " " + path + ": is a folder");
  if (fs::exists(p, ec) ? access(path.c_str(), W_OK) != 0 : access(dir.c_str(), W_OK | X_OK) != 0)
    throw SystemError(std::string(what) + " " + path + ": not writable (" + std::strerror(errno) + ")");
}

void AddProvenance(ImageMetadata& meta) {
  meta["version"] = PF_VERSION;
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char date[32];
  std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", &tm);
  meta["date"] = date;
}

void WritePreviewFor(const std::string& exr, const std::string& png_option, bool no_png, const Image& image) {
  std::string png = png_option;
  if (png.empty() && !no_png) png = std::filesystem::path(exr).replace_extension(".png").string();
  if (!png.empty()) WritePngPreview(png, image, PreviewOptions{.auto_exposure = true});
}

namespace {

std::string OutputFor(const RenderArgs& a) {
  return a.output.empty() ? std::filesystem::path(a.scene).stem().string() + ".exr" : a.output;
}

// Before any work: the EXR and the preview can be written.
void CheckOutputs(const RenderArgs& a) {
  CheckWritable(OutputFor(a), "-o");
  if (!a.png.empty()) CheckWritable(a.png, "--png");
}

}  // namespace

int RunLocalPlan(const RenderArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  CheckOutputs(a);
  PreparedJob job = PrepareJob(a);
  // Exactly the conversions the coordinator applies to a submitted JobSpec.
  const CameraSpec camera = CameraFromProto(job.spec.camera(), "spec.camera");
  const JobRenderSettings settings = SettingsFromProto(job.spec.settings(), "spec.settings");
  PlanSpec plan = PlanFromProto(job.spec.plan(), "spec.plan");
  if (a.max_rounds > 0 && plan.kind == PlanKind::kSkipping) plan.rounds = std::min(plan.rounds, a.max_rounds);
  // The farm's stop rule, here (docs/renderer.md, "Budgets"): the render stops after a whole map
  // (pass, round) once the budget is used up or the targets are met.
  const bool unbiased = !Integrators().FindKind(settings.integrator).UsesPhotonMaps();
  const LocalStopRule stop{
      .time_budget_seconds = a.time_budget,
      .targets =
          JudgedTargets({.target_noise_rms = a.target_noise, .target_error_rms = a.target_error}, unbiased)};
  if (unbiased && a.target_error > 0)
    spdlog::info("--target-error {}: the path tracer is unbiased, its error is its noise", a.target_error);
  if (const std::string problem = LocalStopProblem(stop, plan); !problem.empty()) throw InputError(problem);
  ValidatePlan(plan, camera.width, camera.height);
  // The farm's cap (proto/limits.h), so that a plan renders locally exactly when it can be submitted.
  if (const std::string problem = limits::TaskCountProblem(CountTasks(plan, camera.width, camera.height));
      !problem.empty())
    throw InputError(problem);
  uint64_t total_pixels = 0, total_samples = 0;
  std::vector<TaskSpec> tasks = ExpandPlan(plan, camera.width, camera.height, a.seed);
  for (const TaskSpec& t : tasks) {
    const uint64_t n = CountPixels(t.pixels, camera.width, camera.height);
    total_pixels += n;
    total_samples += n * (t.sample_end - t.sample_begin);
  }
  spdlog::info("plan {}: {} tasks, seed {}", DescribePlan(plan), tasks.size(), a.seed);
  if (plan.kind == PlanKind::kHierarchical) {
    const HierarchyStats st = ComputeHierarchyStats(plan, camera.width, camera.height);
    spdlog::info(
        "hierarchical: Nmax {} maps, navg {:.3f} samples per pixel, {:.3f} evaluations per pixel "
        "(+ localization)",
        st.nmax, st.navg, st.evaluations_per_pixel);
  }

  const SceneRuntime runtime(std::move(job.scene));
  const double load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::atomic<uint64_t> progress{0};
  LocalRenderTotals totals;
  LocalStopReport stopped;
  Image image;
  const auto t1 = std::chrono::steady_clock::now();
  {
    ProgressBar bar(progress, total_pixels, !a.quiet);
    image = RenderPlanLocally(runtime, camera, settings, plan, a.seed, a.threads, &progress, &totals, stop,
                              &stopped);
  }
  if (!stopped.stopped_by.empty()) {
    // The image is the plan's with the units rendered: record that plan, which reproduces it.
    if (plan.kind == PlanKind::kSkipping)
      plan.rounds = uint32_t(stopped.units_done);
    else
      plan.maps = uint32_t(stopped.units_done);
    tasks = ExpandPlan(plan, camera.width, camera.height, a.seed);
    total_samples = 0;
    for (const TaskSpec& t : tasks)
      total_samples += CountPixels(t.pixels, camera.width, camera.height) * (t.sample_end - t.sample_begin);
    spdlog::info("stopped by the {} after {} of {} {}: the image is the plan {}", stopped.stopped_by,
                 stopped.units_done, stopped.units_planned, stopped.unit, PlanRecordText(plan));
  }
  if (stop.targets.any()) {
    const std::string reached = DescribeTargets(stop.targets, stopped.estimates);
    if (stopped.targets_met)
      spdlog::info("target met: {}", reached);
    else
      spdlog::warn("target not met after {} {}: {}; render with a larger budget or more {}",
                   stopped.units_done, stopped.unit, reached, stopped.unit);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  const std::string output =
      a.output.empty() ? std::filesystem::path(a.scene).stem().string() + ".exr" : a.output;
  ImageMetadata meta = {
      {"spp", fmt::format("{}", double(total_samples) / (double(camera.width) * camera.height))},
      {"tasks", std::to_string(tasks.size())},
      {"render_seconds", fmt::format("{:.3f}", seconds)},
      {"rays", std::to_string(totals.rays)},
      {"nonfinite_samples", std::to_string(totals.nonfinite_samples)}};
  // What the image is of, in the keys and values the farm's images carry (docs/farm.md, "Image
  // headers"): every setting with each `auto` as this scene resolved it.
  // The auto choices as a farm job's header lists them: pf's own (the integrator), then the
  // ones the coordinator would make at submission.
  std::vector<AutoChoice> auto_choices = AutoChoicesFromProto(job.spec.auto_settings(), "spec.auto_settings");
  const JobRenderSettings resolved = settings.Resolved(runtime.description, &auto_choices);
  RecordRender({.scene = job.bundle.entry,
                .scene_hash = BundleHash(job.bundle),
                .camera = camera,
                .settings = resolved,
                .plan = plan,
                .seed = a.seed,
                .auto_choices = auto_choices},
               meta);
  if (Integrators().FindKind(settings.integrator).UsesPhotonMaps()) {
    meta["photons.maps_built"] = std::to_string(totals.maps_built);
    meta["photons.emitted"] = std::to_string(totals.photons_emitted);
    meta["photons.stored"] = std::to_string(totals.photons_stored);
    meta["photons.local_pass_gathers"] = std::to_string(totals.gathers);
    meta["photons.cache_interpolations"] = std::to_string(totals.cache_interpolations);
    meta["photons.map_seconds"] = fmt::format("{:.3f}", totals.map_seconds);
  }
  if (stop.any()) {
    meta["stop.stopped_by"] = stopped.stopped_by.empty() ? "plan complete" : stopped.stopped_by;
    meta["stop.units_done"] = fmt::format("{} {}", stopped.units_done, stopped.unit);
    if (stop.time_budget_seconds > 0) meta["stop.time_budget_seconds"] = RealText(stop.time_budget_seconds);
    if (stop.targets.target_noise_rms > 0)
      meta["stop.target_noise_rms"] = RealText(stop.targets.target_noise_rms);
    if (stop.targets.target_error_rms > 0)
      meta["stop.target_error_rms"] = RealText(stop.targets.target_error_rms);
    if (stop.targets.any()) meta["stop.targets_met"] = stopped.targets_met ? "yes" : "no";
  }
  const ErrorEstimates& e = stopped.estimates;
  for (const auto& [key, value] :
       {std::pair{"noise_rms", e.noise}, std::pair{"display_noise_rms", e.display_noise},
        std::pair{"bias_rms", e.bias}, std::pair{"error_rms", e.error}})
    meta[std::string("estimate.") + key] = value < 0 ? "unknown" : fmt::format("{:.6g}", value);
  AddProvenance(meta);
  WriteExr(output, image, meta);
  WritePreviewFor(output, a.png, a.no_png, image);
  if (totals.nonfinite_samples > 0)
    spdlog::warn("{} samples were NaN/Inf and were dropped", totals.nonfinite_samples);
  std::printf("rendered %dx%d locally, %s, %s, %zu tasks in %.2f s (+%.2f s load): %.2f M rays/s -> %s\n",
              camera.width, camera.height,
              std::string(Integrators().FindKind(settings.integrator).name).c_str(),
              DescribePlan(plan).c_str(), tasks.size(), seconds, load_seconds,
              seconds > 0 ? double(totals.rays) / seconds * 1e-6 : 0.0, output.c_str());
  return kExitOk;
}

namespace {

// The pixels [x0, x1) × [y0, y1) of an image (pf diff --region).
Image Crop(const Image& image, const std::array<int, 4>& r) {
  Image out(r[2] - r[0], r[3] - r[1]);
  for (int y = r[1]; y < r[3]; ++y)
    for (int x = r[0]; x < r[2]; ++x) out.at(x - r[0], y - r[1]) = image.at(x, y);
  return out;
}

}  // namespace

int RunDiff(const std::string& a_path, const std::string& ref_path, const std::string& error_image,
            double error_scale, bool json, const std::string& scene_path, const std::string& camera_name,
            const std::vector<int>& region) {
  Image a = ReadExr(a_path);
  Image ref = ReadExr(ref_path);
  const int full_width = ref.width();
  std::vector<uint8_t> excluded;
  if (!scene_path.empty()) {
    RenderArgs args;
    args.camera_name = camera_name;
    const SceneDescription scene = LoadScene(scene_path);
    CameraSpec spec = ChooseCamera(scene, args);
    spec.width = ref.width();
    spec.height = ref.height();
    const EmbreeScene accel(scene);
    excluded =
        EmitterExclusionMask(EmitterCoverage(accel, Camera(spec, scene.origin)), spec.width, spec.height);
  }
  if (!region.empty()) {
    // A part of the image, e.g. a caustic (docs/renderer.md): every metric over its pixels only; the
    // emitter mask is traced at the full resolution first, so its band is where it was.
    const std::array<int, 4> r = {region[0], region[1], region[2], region[3]};
    if (a.width() != ref.width() || a.height() != ref.height())
      throw InputError(a_path + ": size differs from the reference");
    if (!(0 <= r[0] && r[0] < r[2] && r[2] <= ref.width() && 0 <= r[1] && r[1] < r[3] &&
          r[3] <= ref.height()))
      throw InputError("--region: x0,y0,x1,y1 must satisfy 0 <= x0 < x1 <= width, 0 <= y0 < y1 <= height");
    a = Crop(a, r);
    ref = Crop(ref, r);
    if (!excluded.empty()) {
      std::vector<uint8_t> cropped;
      for (int y = r[1]; y < r[3]; ++y)
        for (int x = r[0]; x < r[2]; ++x)
          cropped.push_back(excluded[size_t(y) * size_t(full_width) + size_t(x)]);
      excluded = std::move(cropped);
    }
  }
  const ImageDiffStats d = CompareImages(a, ref, excluded.empty() ? nullptr : &excluded);
  if (json) {
    nlohmann::json j = {{"image", a_path},
                        {"reference", ref_path},
                        {"rmse", d.rmse},
                        {"relative_mse", d.relative_mse},
                        {"rmse_clamped", d.rmse_clamped},
                        {"rmse_display", d.rmse_display},
                        {"display_white", d.display_white},
                        {"max_abs_error", d.max_abs_error},
                        {"max_x", d.max_x},
                        {"max_y", d.max_y},
                        {"mean", d.mean_a},
                        {"reference_mean", d.mean_b},
                        {"pixels", d.pixels}};
    if (d.masked) {
      j["rmse_masked"] = d.rmse_masked;
      j["rmse_lowfreq"] = d.rmse_lowfreq;
      j["mean_masked"] = d.mean_masked_a;
      j["reference_mean_masked"] = d.mean_masked_b;
      j["pixels_masked"] = d.pixels_masked;
      j["blocks_lowfreq"] = d.blocks_lowfreq;
    }
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf(
        "RMSE %.6g (%.4g of display white %.4g)  relative MSE %.6g  max error %.6g at (%d,%d)  mean %.6g vs "
        "%.6g\n",
        d.rmse, d.rmse_display, d.display_white, d.relative_mse, d.max_abs_error, d.max_x, d.max_y, d.mean_a,
        d.mean_b);
    if (d.masked)
      std::printf(
          "RMSE masked %.6g (%zu pixels away from emitters)  low-frequency %.6g (%zu 4x4 blocks)  mean there "
          "%.6g vs %.6g\n",
          d.rmse_masked, d.pixels_masked, d.rmse_lowfreq, d.blocks_lowfreq, d.mean_masked_a, d.mean_masked_b);
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
int RunMerge(const std::vector<std::string>& inputs, const std::string& output, double assume_spp) {
  Image sum;
  double total_weight = 0;
  double seconds = 0;
  std::vector<Image> first_two;
  std::vector<std::string> seeds;
  std::map<std::string, std::string> seed_owner;
  std::map<std::string, std::string> first_value;  // the first value of each SameRenderKey
  ImageMetadata common;                            // what every input's header says alike
  for (const std::string& path : inputs) {
    ImageMetadata meta;
    const Image img = ReadExr(path, &meta);
    if (sum.size() == 0) sum = Image(img.width(), img.height());
    if (img.width() != sum.width() || img.height() != sum.height())
      throw InputError(path + ": size " + std::to_string(img.width()) + "x" + std::to_string(img.height()) +
                       " differs from the first input");
    double w = assume_spp;
    if (meta.count("spp")) {
      char* end = nullptr;
      w = std::strtod(meta["spp"].c_str(), &end);
      if (end == meta["spp"].c_str() || !(w > 0) || !std::isfinite(w))
        throw InputError(path + ": header spp '" + meta["spp"] + "' is not a positive number");
    } else if (assume_spp <= 0) {
      throw InputError(path + ": its header has no spp, so its weight is unknown; pass --assume-spp N");
    }
    // Its seed, or the seeds of a merged image.
    std::vector<std::string> own_seeds;
    if (meta.count("seed")) own_seeds.push_back(meta["seed"]);
    if (meta.count("seeds"))
      for (size_t b = 0, e; b < meta["seeds"].size(); b = e + 1) {
        e = std::min(meta["seeds"].find(',', b), meta["seeds"].size());
        own_seeds.push_back(meta["seeds"].substr(b, e - b));
      }
    for (const std::string& seed : own_seeds) {
      auto [it, fresh] = seed_owner.emplace(seed, path);
      if (!fresh)
        spdlog::warn(
            "{} and {} were both rendered with seed {}: the same noise twice, the average is no better",
            it->second, path, seed);
    }
    // What the image is of (render_header.h SameRenderKey): the scene, the camera, every setting.
    // A key only one of the two holds (a file of an older pf) is not compared.
    // The progressive schedule's settings are in every photon-map image's header, but only the
    // progressive plan reads them: for another plan they say nothing about the image (and their
    // default changed, docs/farm.md "Upgrades").
    const bool progressive = meta.count("plan") && meta["plan"].starts_with("progressive");
    const std::string progressive_key = SettingHeaderKey(kProgressiveSettingPrefix);
    for (const auto& [key, value] : meta) {
      if (!SameRenderKey(key) || (!progressive && key.starts_with(progressive_key))) continue;
      auto [it, fresh] = first_value.emplace(key, value);
      if (!fresh && it->second != value)
        spdlog::warn("{}: {} {} differs from the first input's {}: the average mixes different renders", path,
                     key, value, it->second);
    }
    if (first_two.empty()) {  // the first input
      for (const auto& [key, value] : meta)
        if (SameRenderKey(key) || key == "plan" || key.starts_with(kAutoHeaderPrefix))
          common.emplace(key, value);
    } else {
      for (auto it = common.begin(); it != common.end();)
        it = meta.count(it->first) && meta[it->first] == it->second ? std::next(it) : common.erase(it);
    }
    if (meta.count("render_seconds")) seconds += std::stod(meta["render_seconds"]);
    seeds.insert(seeds.end(), own_seeds.begin(), own_seeds.end());
    for (size_t i = 0; i < img.size(); ++i) sum[i] += img[i] * float(w);
    total_weight += w;
    if (first_two.size() < 2) first_two.push_back(img);
  }
  for (Rgb& c : sum.pixels()) c *= float(1.0 / total_weight);
  // The merged image is of what every input was of: those keys carry over, so it can be merged again.
  ImageMetadata meta = common;
  meta.insert({{"spp", fmt::format("{}", total_weight)},
               {"render_seconds", fmt::format("{:.1f}", seconds)},
               {"merged_from", fmt::format("{}", fmt::join(inputs, ","))},
               {"seeds", fmt::format("{}", fmt::join(seeds, ","))}});
  if (first_two.size() == 2) {
    const double noise = CompareImages(first_two[0], first_two[1]).rmse / 2.0;
    meta["estimated_noise_rmse"] = fmt::format("{:.6g}", noise);
    std::printf("estimated remaining noise (RMSE of the two halves / 2): %.6g\n", noise);
  }
  WriteExr(output, sum, meta, ExrCompression::kPiz);
  std::printf("merged %zu images, %g spp in all -> %s\n", inputs.size(), total_weight, output.c_str());
  return kExitOk;
}

int RunPreview(const std::string& image_path, const std::string& output, const std::string& exposure_of,
               double stops) {
  const Image image = ReadExr(image_path);
  PreviewOptions o{.exposure_stops = stops, .auto_exposure = exposure_of.empty()};
  if (!exposure_of.empty()) o.exposure_stops += std::log2(AutoExposureScale(ReadExr(exposure_of)));
  WritePngPreview(output, image, o);
  std::printf("%s -> %s (scale %.6g)\n", image_path.c_str(), output.c_str(), PreviewScale(image, o));
  return kExitOk;
}

int RunInfo(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".exr") {
    ImageMetadata meta;
    const Image image = ReadExr(path, &meta);
    double sum = 0;
    for (const Rgb& c : image.pixels()) sum += (double(c.r) + c.g + c.b) / 3.0;
    std::printf("image       %s\nsize        %dx%d\nmean        %.6g\n", path.c_str(), image.width(),
                image.height(), image.size() ? sum / double(image.size()) : 0.0);
    for (const auto& [key, value] : meta) std::printf("%-11s %s\n", key.c_str(), value.c_str());
    return kExitOk;
  }
  const SceneDescription scene = LoadScene(path);
  const Bounds3 frame_bounds = scene.ComputeBounds();  // world bounds: + origin (scene_frame.h)
  const Vec3d lo = frame_bounds.Empty() ? Vec3d(frame_bounds.lo) : Vec3d(frame_bounds.lo) + scene.origin;
  const Vec3d hi = frame_bounds.Empty() ? Vec3d(frame_bounds.hi) : Vec3d(frame_bounds.hi) + scene.origin;
  std::printf("scene       %s\ntriangles   %zu\nemitting    %zu triangles in %u lights\nmaterials   %zu\n",
              path.c_str(), scene.NumTriangles(), scene.NumEmissiveTriangles(), scene.num_lights,
              scene.materials.size());
  if (scene.origin == Vec3d()) {
    std::printf("bounds      (%g, %g, %g) .. (%g, %g, %g)\n", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
  } else {
    std::printf("bounds      (%.10g, %.10g, %.10g) .. (%.10g, %.10g, %.10g)\n", lo.x, lo.y, lo.z, hi.x, hi.y,
                hi.z);
    std::printf("frame       positions stored relative to (%.17g, %.17g, %.17g) (far from the origin)\n",
                scene.origin.x, scene.origin.y, scene.origin.z);
  }
  for (const CameraSpec& c : scene.cameras)
    std::printf("camera      %s: eye %s look-at %s up %s fov %g res %dx%d\n", c.name.c_str(),
                FormatVec(c.eye).c_str(), FormatVec(c.look_at).c_str(), FormatVec(c.up).c_str(),
                c.vfov_degrees, c.width, c.height);
  // What the photon-map renderer would choose for this scene where a setting is left `auto`
  // (JobRenderSettings::Resolved; the same choice pf render and the coordinator log).
  JobRenderSettings photon_map;
  photon_map.integrator = IntegratorKind::kPhotonMap;
  std::vector<AutoChoice> choices;
  photon_map.Resolved(scene, &choices);
  for (const AutoChoice& c : choices)
    std::printf("auto        %s = %s: %s\n", c.setting.c_str(), c.value.c_str(), c.reason.c_str());
  std::printf("warnings    %zu\n", scene.warnings.size());
  for (const std::string& w : scene.warnings) std::printf("  %s\n", w.c_str());
  return kExitOk;
}

}  // namespace pf
