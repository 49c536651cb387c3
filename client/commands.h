#pragma once
// The `pf` subcommands, one function each; main.cpp only wires the command line to them.
// Exit codes (documented in `pf --help`): 0 success, 1 runtime failure (I/O, Embree, RPC, the
// job failed or was cancelled), 2 usage error, 3 invalid input (scene/manifest file:line, or a
// request the coordinator rejected as INVALID_ARGUMENT / NOT_FOUND / RESOURCE_EXHAUSTED),
// 130 interrupted (Ctrl-C, SIGTERM).

#include <string>
#include <vector>

#include "client/render_args.h"
#include "common/image/exr_io.h"
#include "common/image/image.h"

namespace pf {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitBadInput = 3;
inline constexpr int kExitInterrupted = 130;

// Connection to a running coordinator (submit, watch, get, list, cancel).
struct FarmArgs {
  std::string coordinator;                // HOST:PORT; default $PF_COORDINATOR
  std::string token_file;                 // default $PF_TOKEN
  std::string tls_ca, tls_cert, tls_key;  // TLS (rpc/grpc_channel.h ResolveClientTls)
  double timeout = 60;                    // deadline of each call, seconds
};

// In-process (client/local_commands.cpp).
int RunLocalPlan(const RenderArgs& a);  // every render without --workers: the job's plan in-process
// `scene` (optional): the scene the images show, for the masked metrics (rmse_masked,
// rmse_lowfreq); its camera `camera_name` (default: the first) at the images' resolution.
int RunDiff(const std::string& a_path, const std::string& ref_path, const std::string& error_image,
            double error_scale, bool json, const std::string& scene = "", const std::string& camera_name = "",
            const std::vector<int>& region = {});
// Inputs without "spp" in their header weigh `assume_spp` (0: refused with InputError).
int RunMerge(const std::vector<std::string>& inputs, const std::string& output, double assume_spp = 0);
// PNG of an EXR: auto exposure of `image`, or of `exposure_of` (so renders of one scene share
// one exposure and compare by eye), plus `stops`.
int RunPreview(const std::string& image, const std::string& output, const std::string& exposure_of,
               double stops);
int RunInfo(const std::string& path);                     // a scene, or an EXR's size and header
int RunSettings(const std::string& name, bool markdown);  // the settings table (settings_command.cpp)
// docs/settings.md: the reference page of every render setting (pf settings --markdown).
std::string SettingsReferencePage();

// Farm (client/farm_commands.cpp).
int RunFarmRender(const RenderArgs& a);  // --workers N: a local coordinator + N workers
int RunSubmit(const RenderArgs& a, const FarmArgs& f);
int RunWatch(const FarmArgs& f, const std::string& job_id, const std::string& output, double interval,
             bool json, bool quiet);
int RunGet(const FarmArgs& f, const std::string& job_id, const std::string& output, const std::string& png);
int RunList(const FarmArgs& f, bool all, bool json);
int RunCancel(const FarmArgs& f, const std::string& job_id);
int RunPause(const FarmArgs& f, const std::string& job_id, bool paused);  // pf pause / pf resume
// pf delete: each job (an id or a unique prefix) in turn; a failure is reported and the others
// still go. The exit code of the last failure (FAILED_PRECONDITION for a live job: 1).
int RunDelete(const FarmArgs& f, const std::vector<std::string>& job_ids);
// pf purge: deletes the succeeded, failed and cancelled jobs that finished more than
// `older_than_seconds` ago (only lists them with `dry_run`).
int RunPurge(const FarmArgs& f, double older_than_seconds, bool dry_run);
// pf requeue (docs/farm.md "Requeueing a job"): a new job that re-runs or continues a finished
// one; its id on stdout. `length_flag`/`length`: --passes, --maps or --rounds and its value (0:
// unchanged), checked against the job's plan; a stop-rule value < 0 keeps the job's.
struct RequeueArgs {
  std::string job_id;
  std::string length_flag;
  uint32_t length = 0;
  double time_budget = -1, target_noise = -1, target_error = -1;
};
int RunRequeue(const FarmArgs& f, const RequeueArgs& r);
int RunWorkers(const FarmArgs& f, bool json);
int RunEvents(const FarmArgs& f, const std::string& job_id, bool json);

// The exit code for an exception escaping a command (and the message printed).
int ExitCodeFor(const std::exception& e);

// Fails (SystemError naming the path) unless `path` can be written: its folder exists and is
// writable, and the file, if present, is writable. Called before a render, not after it.
void CheckWritable(const std::string& path, const char* what);

// Header entries every image pf writes carries: version and UTC date.
void AddProvenance(ImageMetadata& meta);

// Writes a PNG preview next to an EXR unless disabled (--png / --no-png semantics).
void WritePreviewFor(const std::string& exr, const std::string& png, bool no_png, const Image& image);

}  // namespace pf
