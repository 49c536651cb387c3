// pf — the photonfarm command-line client.
//
//   pf render SCENE [options]                 the farm's default plan (one map, 64-px tiles), in this process
//   pf render SCENE --plan P [--local-only]   the same plan a farm job runs, in this process
//   pf render SCENE --workers N [--plan P]    start a coordinator + N workers on loopback, render, stop
//   pf submit SCENE [options]                 upload the scene, submit a job, print its id
//   pf watch JOB [-o out.exr]                 progress (and snapshots) until the job ends
//   pf get JOB -o out.exr                     the current merged image
//   pf list / cancel / pause / resume JOB     jobs of a coordinator
//   pf delete JOB... / pf purge --older-than  finished jobs and their files go
//   pf requeue JOB [--passes N]              a finished job re-run or continued
//   pf diff / merge / preview / info          images and scenes
//
// Exit codes: client/commands.h (0 ok, 1 failure, 2 usage, 3 invalid input, 130 interrupted).
#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cctype>
#include <filesystem>

#include "client/commands.h"
#include "client/did_you_mean.h"
#include "client/interrupt.h"
#include "common/core/duration_text.h"
#include "common/core/error.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "rpc/address.h"

namespace {

// Refuses a file name whose extension does not say what pf writes there (-o x.png used to get
// EXR bytes, and the preview then overwrote them).
CLI::Validator Extension(std::vector<std::string> allowed, std::string what) {
  std::string desc;
  for (const std::string& e : allowed) desc += (desc.empty() ? "" : "|") + e;
  return CLI::Validator(
      [allowed, what](std::string& value) -> std::string {
        std::string ext = std::filesystem::path(value).extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
        if (std::find(allowed.begin(), allowed.end(), ext) != allowed.end()) return "";
        std::string list;
        for (const std::string& e : allowed) list += (list.empty() ? "" : " or ") + e;
        return "'" + value + "': " + what + ", so its name must end in " + list;
      },
      desc);
}

const CLI::Validator kCoordinatorAddress(
    [](std::string& value) { return pf::CoordinatorAddressProblem(value); }, "HOST:PORT");

// The farm's limits (proto/convert.h), which pf's flags check too: one source of truth.
std::string LimitsHelp() {
  return fmt::format(
      "Limits (the farm's, checked before anything runs): --photons <= {} per map, --k <= {}, --res <= {}\n"
      "per side and {} pixels in all, --spp <= {}, --shadow-rays and --local-pass <= {}.\n",
      pf::kMaxPhotonsPerMap, pf::kMaxK, pf::kMaxImageSide, pf::kMaxImagePixels, pf::kMaxSamplesPerPixel,
      pf::kMaxShadowRays);
}

void AddFarmOptions(CLI::App* app, pf::FarmArgs& f) {
  app->add_option("--coordinator", f.coordinator, "Coordinator HOST:PORT (default $PF_COORDINATOR)")
      ->check(kCoordinatorAddress);
  app->add_option(
      "--token-file", f.token_file,
      "File holding the client's bearer token, one line (default $PF_TOKEN_FILE, else $PF_TOKEN)");
  app->add_option("--tls-ca", f.tls_ca,
                  "PEM roots of the coordinator's TLS certificate: connect with TLS (default $PF_TLS_CA)");
  app->add_option("--tls-cert", f.tls_cert, "PEM client certificate (with --tls-key; default $PF_TLS_CERT)");
  app->add_option("--tls-key", f.tls_key, "PEM private key of --tls-cert (default $PF_TLS_KEY)");
  app->add_option("--timeout", f.timeout, "Deadline of each call, seconds")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 86400.0));
}

void AddOutputOptions(CLI::App* app, pf::RenderArgs& a, bool all) {
  auto more = [all](CLI::Option* o) { return all ? o : o->group(""); };
  app->add_option("-o,--output", a.output, "Output EXR (default: <scene>.exr; a PNG preview beside it)")
      ->check(Extension({".exr"}, "the output is an OpenEXR file (the PNG preview goes to --png)"));
  more(app->add_option("--png", a.png, "PNG preview path (default: output with .png)")
           ->check(Extension({".png"}, "the preview is a PNG file")));
  more(app->add_flag("--no-png", a.no_png, "Do not write a PNG preview"));
  app->add_flag("-q,--quiet", a.quiet, "No progress bar");
}

// `pf render --help-all`: --help with every option (--help shows the common ones).
bool TakeHelpAll(int argc, char** argv) {
  bool found = false;
  for (int i = 1; i < argc; ++i)
    if (std::string_view(argv[i]) == "--help-all") {
      argv[i] = const_cast<char*>("--help");
      found = true;
    }
  return found;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace pf;
  InstallInterruptHandling();
  const bool all = TakeHelpAll(argc, argv);
  CLI::App app{fmt::format(
      "pf — photonfarm, photorealistic rendering with the photon map (Wald 1999).\n\n"
      "Examples:\n"
      "  pf render scenes/cornell-box/cornell-box.json --workers 2 -o cornell.exr\n"
      "  pf render scenes/cornell-box/cornell-box.json --spp 256 -o cornell.exr\n"
      "  pf render scenes/cornell-box/cornell-box.json --integrator photonmap --plan skipping --stride 2 \\\n"
      "      --rounds 4 --set photons=20000 --spp 1 --local-only -o local.exr\n"
      "  pf submit scenes/office3/office.mgf --integrator photonmap --plan skipping --coordinator HOST:PORT\n"
      "  pf watch job-1 -o office.exr;  pf get job-1 -o office.exr;  pf list --all;  pf cancel job-1\n"
      "  pf diff cornell.exr scenes/cornell-box/reference-256.exr --error-image err.png\n"
      "  pf diff cornell.exr scenes/cornell-box/reference-256.exr --scene "
      "scenes/cornell-box/cornell-box.json\n"
      "  pf preview cornell.exr -o cornell.png --exposure-of scenes/cornell-box/reference-256.exr\n"
      "  pf info scenes/scene8/scene8.json;  pf info cornell.exr\n"
      "  pf workers --coordinator HOST:PORT;  pf events job-1 --coordinator HOST:PORT\n\n"
      "{}"
      "Render settings: --set NAME=VALUE, --settings FILE or a scene manifest's \"settings\" (which the\n"
      "command line overrides); pf settings lists them, docs/settings.md explains them.\n"
      "pf render --help shows the common options, pf render --help-all all of them.\n\n"
      "Exit codes: 0 ok, 1 runtime failure (I/O, Embree, RPC; the job failed or was cancelled),\n"
      "2 usage error, 3 invalid input (scene/manifest errors as file:line: reason; requests the\n"
      "coordinator rejects as INVALID_ARGUMENT, NOT_FOUND or RESOURCE_EXHAUSTED), 130 interrupted.",
      LimitsHelp())};
  app.require_subcommand(1);
  app.fallthrough();  // --log-level may follow the subcommand
  std::string log_level = "info";
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "warning", "error", "critical", "off"}));
  app.set_version_flag("--version", "pf " PF_VERSION);

  RenderArgs ra;
  CLI::App* render = app.add_subcommand(
      "render",
      "Render a scene (.json manifest, .mgf or .obj) to EXR + PNG: in this process, or with --workers N on "
      "a\n"
      "coordinator and N worker processes that pf starts on loopback and stops afterwards");
  render->footer("Every render setting: --set NAME=VALUE (pf settings lists them); every option: --help-all");
  auto more = [all](CLI::Option* o) { return all ? o : o->group(""); };
  AddSceneOptions(render, ra, all);
  AddPlanOptions(render, ra, all);
  AddOutputOptions(render, ra, all);
  more(render
           ->add_option("--threads", ra.threads,
                        "Threads (0 = all cores; with --workers: per worker, default cores/N)")
           ->capture_default_str()
           ->check(CLI::Range(0, 1024)));
  render
      ->add_option("--workers", ra.workers,
                   "Render on a local farm of N pf-worker processes (default plan: multiple-maps, 1 map, "
                   "64-pixel tiles)")
      ->check(CLI::Range(0, 256));
  more(render->add_flag(
      "--local-only", ra.local_only,
      "Run the plan in this process (same tasks, seeds and merge as the farm: bit-identical image)"));
  more(render->add_option("--coordinator-bin", ra.coordinator_bin,
                          "pf-coordinator executable (default: next to pf)"));
  more(render->add_option("--worker-bin", ra.worker_bin, "pf-worker executable (default: next to pf)"));
  more(render
           ->add_option("--coordinator-arg", ra.coordinator_args,
                        "Extra flag for the local coordinator (repeatable)")
           ->allow_extra_args(false));
  more(render->add_option("--worker-arg", ra.worker_args, "Extra flag for each local worker (repeatable)")
           ->allow_extra_args(false));
  more(render->add_flag("--keep-farm-dir", ra.keep_farm_dir,
                        "Keep the local farm's folder (logs, SQLite) afterwards"));

  RenderArgs sa;
  sa.submit = true;
  FarmArgs sf;
  CLI::App* submit =
      app.add_subcommand("submit", "Upload a scene and submit a render job; prints the job id");
  AddSceneOptions(submit, sa, true);
  AddPlanOptions(submit, sa, true);
  submit->add_option("--after", sa.after,
                     "Start once this job has succeeded (fail if it fails or is cancelled); repeatable");
  AddFarmOptions(submit, sf);

  FarmArgs wf;
  std::string watch_job, watch_out;
  double watch_interval = 0.5;
  bool watch_json = false, watch_quiet = false;
  CLI::App* watch = app.add_subcommand(
      "watch",
      "Follow a job until it ends: progress, ETA, estimated noise; with -o the EXR is rewritten\n"
      "atomically with every snapshot and holds the final image at the end");
  watch->add_option("job", watch_job, "Job id")->required();
  watch->add_option("-o,--output", watch_out, "EXR to keep up to date")
      ->check(Extension({".exr"}, "the output is an OpenEXR file"));
  watch->add_option("--interval", watch_interval, "Minimum seconds between updates")->capture_default_str();
  watch->add_flag("--json", watch_json, "One JSON object per update on stdout");
  watch->add_flag("-q,--quiet", watch_quiet, "No progress bar");
  AddFarmOptions(watch, wf);

  FarmArgs gf;
  std::string get_job, get_out, get_png;
  CLI::App* get = app.add_subcommand("get", "Fetch a job's current merged image (EXR, linear float)");
  get->add_option("job", get_job, "Job id")->required();
  get->add_option("-o,--output", get_out, "Output EXR")
      ->required()
      ->check(Extension({".exr"}, "the output is an OpenEXR file"));
  get->add_option("--png", get_png, "Also write a PNG preview")
      ->check(Extension({".png"}, "the preview is a PNG file"));
  AddFarmOptions(get, gf);

  FarmArgs lf;
  bool list_all = false, list_json = false;
  CLI::App* list = app.add_subcommand("list", "List the coordinator's jobs");
  list->add_flag("-a,--all", list_all, "Include finished jobs");
  list->add_flag("--json", list_json, "JSON output");
  AddFarmOptions(list, lf);

  FarmArgs wkf;
  bool workers_json = false;
  CLI::App* workers = app.add_subcommand(
      "workers",
      "List the workers the coordinator has seen (stored across its restarts): task, tasks done, photons/s");
  workers->add_flag("--json", workers_json, "JSON output");
  AddFarmOptions(workers, wkf);

  FarmArgs ef;
  std::string events_job;
  bool events_json = false;
  CLI::App* events = app.add_subcommand(
      "events",
      "A job's task events since the coordinator started: which worker ran which task, retries, failures");
  events->add_option("job", events_job, "Job id")->required();
  events->add_flag("--json", events_json, "JSON output");
  AddFarmOptions(events, ef);

  FarmArgs cf;
  std::string cancel_job;
  CLI::App* cancel = app.add_subcommand("cancel", "Cancel a job (its merged image stays retrievable)");
  cancel->add_option("job", cancel_job, "Job id")->required();
  AddFarmOptions(cancel, cf);

  FarmArgs pf_args, rf;
  std::string pause_job, resume_job;
  CLI::App* pause = app.add_subcommand(
      "pause", "Pause a queued or running job: no new tasks start, running ones finish and are merged");
  pause->add_option("job", pause_job, "Job id")->required();
  AddFarmOptions(pause, pf_args);
  CLI::App* resume = app.add_subcommand("resume", "Resume a paused job");
  resume->add_option("job", resume_job, "Job id")->required();
  AddFarmOptions(resume, rf);

  FarmArgs qf;
  RequeueArgs requeue_args;
  uint32_t requeue_passes = 0, requeue_maps = 0, requeue_rounds = 0;
  CLI::App* requeue = app.add_subcommand(
      "requeue", "A new job from a finished one: re-runs what it did not render, or continues it further");
  requeue
      ->add_option("job", requeue_args.job_id, "A succeeded, failed or cancelled job (id or unique prefix)")
      ->required();
  CLI::Option* rq_passes =
      requeue->add_option("--passes", requeue_passes, "Continue a progressive job to this many passes")
          ->check(CLI::PositiveNumber);
  CLI::Option* rq_maps =
      requeue->add_option("--maps", requeue_maps, "Continue a multiple-maps job to this many maps")
          ->check(CLI::PositiveNumber);
  CLI::Option* rq_rounds =
      requeue->add_option("--rounds", requeue_rounds, "Continue a skipping job to this many rounds")
          ->check(CLI::PositiveNumber);
  rq_passes->excludes(rq_maps)->excludes(rq_rounds);
  rq_maps->excludes(rq_rounds);
  requeue
      ->add_option("--time-budget", requeue_args.time_budget,
                   "New stop rule: seconds of rendering (0 = none)")
      ->check(CLI::NonNegativeNumber);
  requeue
      ->add_option("--target-error", requeue_args.target_error,
                   "New stop rule: estimated error RMS (0 = none)")
      ->check(CLI::NonNegativeNumber);
  requeue
      ->add_option("--target-noise", requeue_args.target_noise,
                   "New stop rule: estimated noise RMS (0 = none)")
      ->check(CLI::NonNegativeNumber);
  AddFarmOptions(requeue, qf);

  FarmArgs df, uf;
  std::vector<std::string> delete_jobs;
  CLI::App* del = app.add_subcommand(
      "delete", "Delete finished jobs: their image, checkpoint and photon maps no other job uses");
  del->add_option("job", delete_jobs,
                  "Job ids (or unique prefixes); a queued or running job: cancel it first")
      ->required();
  AddFarmOptions(del, df);
  std::string purge_age;
  bool purge_dry_run = false;
  CLI::App* purge = app.add_subcommand("purge", "Delete the jobs that finished more than a while ago");
  purge->add_option("--older-than", purge_age, "Finished more than this long ago: 7d, 12h, 30m, or seconds")
      ->required()
      ->check(pf::DurationTextProblem);
  purge->add_flag("--dry-run", purge_dry_run, "Only list the jobs it would delete");
  AddFarmOptions(purge, uf);

  std::string diff_a, diff_ref, diff_err, diff_scene, diff_camera;
  double diff_scale = 0;
  bool diff_json = false;
  CLI::App* diff =
      app.add_subcommand("diff", "Compare an image with a reference: RMSE, relative MSE, max error");
  diff->add_option("image", diff_a, "Image to judge (EXR)")->required()->check(CLI::ExistingFile);
  diff->add_option("reference", diff_ref, "Reference (EXR)")->required()->check(CLI::ExistingFile);
  diff->add_option("--error-image", diff_err, "Write a false-colour error image (.png or .exr)")
      ->check(Extension({".png", ".exr"}, "the error image is a PNG or OpenEXR file"));
  diff->add_option("--error-scale", diff_scale, "Error mapped to the top of the colour ramp (default: max)");
  diff->add_flag("--json", diff_json, "Print JSON instead of a line");
  diff->add_option(
          "--scene", diff_scene,
          "The scene shown: adds rmse_masked (without the emitters seen directly and a 2-pixel band "
          "around them), rmse_lowfreq (RMSE of 4x4-pixel block means outside that mask) and the two "
          "images' means outside it; emitters are found by tracing the scene's camera at the images' "
          "resolution")
      ->check(CLI::ExistingFile);
  diff->add_option("--camera", diff_camera, "With --scene: the named camera (default: the scene's first)");
  std::vector<int> diff_region;
  diff->add_option("--region", diff_region,
                   "Compare only the pixels x0 <= x < x1, y0 <= y < y1 (e.g. a caustic): x0,y0,x1,y1")
      ->delimiter(',')
      ->expected(4);

  std::vector<std::string> merge_inputs;
  std::string merge_output;
  double merge_assume_spp = 0;
  CLI::App* merge = app.add_subcommand(
      "merge",
      "Average EXRs rendered with different seeds, weighted by their spp (the 'spp' of each header).\n"
      "Refuses an EXR without spp unless --assume-spp; warns about repeated seeds (the same noise twice)\n"
      "and about images of another scene, camera or setting (the header's scene.hash, camera.*, settings.*)");
  merge->add_option("inputs", merge_inputs, "EXR files")->required()->check(CLI::ExistingFile);
  merge->add_option("-o,--output", merge_output, "Output EXR (PIZ-compressed)")
      ->required()
      ->check(Extension({".exr"}, "the output is an OpenEXR file"));
  merge->add_option("--assume-spp", merge_assume_spp, "Weight of inputs whose header has no spp")
      ->check(CLI::PositiveNumber);

  std::string preview_in, preview_out, preview_ref;
  double preview_stops = 0;
  CLI::App* preview = app.add_subcommand(
      "preview",
      "Write an EXR's PNG preview (sRGB). Exposure: automatic (99th-percentile luminance -> 0.9),\n"
      "or that of --exposure-of REF so that several renders of one scene compare by eye");
  preview->add_option("image", preview_in, "EXR to show")->required()->check(CLI::ExistingFile);
  preview->add_option("-o,--output", preview_out, "Output PNG")
      ->required()
      ->check(Extension({".png"}, "the preview is a PNG file"));
  preview
      ->add_option("--exposure-of", preview_ref,
                   "Use this EXR's automatic exposure instead of the image's own")
      ->check(CLI::ExistingFile);
  preview->add_option("--exposure", preview_stops, "Stops added on top (+1 = twice as bright)")
      ->capture_default_str();

  std::string settings_name;
  bool settings_markdown = false;
  CLI::App* settings = app.add_subcommand(
      "settings",
      "List the render settings (--set NAME=VALUE), or explain one: range, default, what it needs");
  settings->add_option("name", settings_name, "A setting's name");
  settings->add_flag("--markdown", settings_markdown, "The reference page docs/settings.md");

  std::string info_scene;
  CLI::App* info = app.add_subcommand(
      "info", "Print what a scene contains (counts, bounds, cameras, warnings), or an EXR's size and header");
  info->add_option("scene", info_scene, "Scene manifest, geometry file or EXR image")->required();

  try {
    app.parse(argc, argv);
    if (*render && ra.local_only && ra.workers > 0)
      throw CLI::ValidationError("--local-only", "cannot be combined with --workers");
    // A plain render (no --plan, --local-only or --workers) is the default plan in this process:
    // the other plan and farm options would be silently ignored.
    // With a budget it runs the photon map's progressive plan (docs/renderer.md, "Budgets"), whose
    // most passes --passes sets (PrepareJob refuses it if the budget's plan is the path tracer's).
    const bool budget = ra.time_budget > 0 || ra.target_noise > 0 || ra.target_error > 0;
    if (*render && ra.workers == 0 && !ra.local_only && ra.plan.empty())
      for (const char* opt :
           {"--maps", "--passes", "--stride", "--rounds", "--tile", "--max-rounds", "--priority", "--name"})
        if (render->count(opt) > 0 && !(budget && std::string_view(opt) == "--passes"))
          throw CLI::ValidationError(
              opt, std::string(
                       "applies to plan renders only (add --plan P, --local-only or "
                       "--workers N); a plain render runs the default plan (one map, 64-pixel tiles) here"));
    for (auto [cmd, args] : {std::pair{render, &ra}, std::pair{submit, &sa}}) {
      if (*cmd) CheckSettingArgs(*args);
      args->spp_given = cmd->count("--spp") > 0;
    }
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    for (const std::string& hint : pf::DidYouMean(app)) std::fprintf(stderr, "%s\n", hint.c_str());
    return code == 0 ? kExitOk : kExitUsage;
  }
  // Logs go to stderr: stdout carries results (`pf submit` prints only the job id).
  spdlog::set_default_logger(spdlog::stderr_color_mt("pf"));
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v");
  try {
    if (*render) {
      ApplyManifestSettings(ra);
      if (ra.workers > 0) return RunFarmRender(ra);
      // One render path: a plain render is the farm's default plan (multiple-maps, --maps 1, --tile
      // 64) run here, so `pf render`, `--local-only` and `--workers N` give the same image.
      return RunLocalPlan(ra);
    }
    if (*submit) {
      ApplyManifestSettings(sa);
      return RunSubmit(sa, sf);
    }
    if (*workers) return RunWorkers(wkf, workers_json);
    if (*events) return RunEvents(ef, events_job, events_json);
    if (*watch) return RunWatch(wf, watch_job, watch_out, watch_interval, watch_json, watch_quiet);
    if (*get) return RunGet(gf, get_job, get_out, get_png);
    if (*list) return RunList(lf, list_all, list_json);
    if (*cancel) return RunCancel(cf, cancel_job);
    if (*pause) return RunPause(pf_args, pause_job, true);
    if (*resume) return RunPause(rf, resume_job, false);
    if (*del) return RunDelete(df, delete_jobs);
    if (*requeue) {
      for (auto [option, value] : {std::pair{rq_passes, requeue_passes}, std::pair{rq_maps, requeue_maps},
                                   std::pair{rq_rounds, requeue_rounds}})
        if (option->count() > 0) {
          requeue_args.length_flag = option->get_name();
          requeue_args.length = value;
        }
      return RunRequeue(qf, requeue_args);
    }
    if (*purge) return RunPurge(uf, ParseDurationText(purge_age, "--older-than"), purge_dry_run);
    if (*diff)
      return RunDiff(diff_a, diff_ref, diff_err, diff_scale, diff_json, diff_scene, diff_camera, diff_region);
    if (*info) return RunInfo(info_scene);
    if (*settings) return RunSettings(settings_name, settings_markdown);
    if (*merge) return RunMerge(merge_inputs, merge_output, merge_assume_spp);
    if (*preview) return RunPreview(preview_in, preview_out, preview_ref, preview_stops);
  } catch (const std::exception& e) {
    const int code = ExitCodeFor(e);
    if (code == kExitInterrupted)
      std::fprintf(stderr, "\ninterrupted\n");
    else
      spdlog::error("{}", e.what());
    return code;
  }
  return kExitUsage;
}
