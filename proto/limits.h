#pragma once
// The limits of the wire protocol in one place (docs/security.md, "Limits"): the coordinator
// enforces them, pf and the worker use the same constants, farm.proto's comments cite this file.
// Every string taken from a request is checked here before it is used, logged or echoed.

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "common/core/error.h"
#include "common/render/setting_limits.h"
#include "common/scene/scene_bundle.h"

namespace pf::limits {

inline constexpr size_t kMaxIdBytes = 128;                // job_id, lease_id, scene_hash in requests
inline constexpr size_t kMaxWorkerIdBytes = 256;          // LeaseTaskRequest.worker_id
inline constexpr size_t kMaxJobNameBytes = 256;           // JobSpec.name
inline constexpr size_t kMaxAutoSettings = 16;            // JobSpec.auto_settings
inline constexpr size_t kMaxDependencies = 16;            // JobSpec.after
inline constexpr size_t kMaxFrames = 10000;               // JobSpec.animation.cameras
inline constexpr size_t kMaxAutoSettingTextBytes = 1024;  // each of their texts
inline constexpr size_t kMaxEchoBytes = 64;               // of an untrusted string quoted in a message or log
inline constexpr size_t kMaxReasonBytes = 4096;           // FailTaskRequest.reason (cut, then sanitized)

// Tasks of one job (JobSpec.plan expanded): the coordinator keeps a TaskSpec and a TaskRuntime
// per task in memory and a row per task in SQLite. The one cap for the farm (SubmitJob,
// RESOURCE_EXHAUSTED) and for `pf render`'s local plan (exit 3); common/plan/ has no cap of its
// own. Exactly kMaxTasksPerJob tasks are accepted.
inline constexpr uint64_t kMaxTasksPerJob = uint64_t(1) << 20;

// The plausibility bound of a task result (docs/security.md, "Results"): a pixel's channel sum
// over n samples above n × kResultRadianceFactor × (the scene's brightest emitter radiance) is
// not merged unless a second worker reproduces it bit for bit. Not a physical limit of one
// sample (Monte Carlo next-event and density estimates have unbounded tails), hence the
// confirmation instead of a hard rejection.
inline constexpr double kResultRadianceFactor = 1024;

// gRPC message sizes of the coordinator (server/coordinator.h says why these): receive = a 64 MiB
// scene bundle or the largest task result, + 1 MiB framing; send = 16 MiB (images and bundles
// stream in 1 MiB chunks; the largest unary answer is a ListJobs page).
inline constexpr int kMaxReceiveMessageBytes = (64 << 20) + (1 << 20);
inline constexpr int kMaxSendMessageBytes = 16 << 20;

// Scene bundles: defined beside the bundle code (common/ cannot include proto/), named here so
// that this file lists every limit.
using pf::kMaxBundleBytes;
using pf::kMaxBundleFiles;
using pf::kMaxBundlePathBytes;

// ListJobs pages (ListJobsRequest.page_size): 0 asks for the default; more is capped.
inline constexpr uint32_t kDefaultListJobsPageSize = 100;
inline constexpr uint32_t kMaxListJobsPageSize = 1000;

// "" if a plan of `tasks` tasks is within kMaxTasksPerJob, else the message (field spec.plan).
inline std::string TaskCountProblem(uint64_t tasks) {
  if (tasks <= kMaxTasksPerJob) return "";
  return "spec.plan: " + std::to_string(tasks) + " tasks exceed the limit of " +
         std::to_string(kMaxTasksPerJob) + " per job; use larger tiles or fewer maps/rounds";
}
}  // namespace pf::limits
namespace pf {
// A job's values (docs/farm.md; over them: RESOURCE_EXHAUSTED, LimitError in proto/convert.h).
inline constexpr uint32_t kMaxImageSide = 8192;
inline constexpr uint64_t kMaxImagePixels = uint64_t(4096) * 4096;
// kMaxPhotonsPerMap, kMaxCausticSplit, kMaxK, kMaxShadowRays: common/render/setting_limits.h
// (the settings table's ranges).
inline constexpr uint32_t kMaxSamplesPerPixel = 1u << 16;
// Camera.vfov_degrees, checked after conversion to float (the worker's type).
inline constexpr float kMinVfovDegrees = 0.001f;
inline constexpr float kMaxVfovDegrees = 179.9f;
}  // namespace pf
namespace pf::limits {

// The worker id a worker announces in every WorkerService call's metadata, so that a call the
// coordinator's auth hook refuses (a wrong token) can be listed under it in `pf workers`: that
// hook sees no peer address (docs/farm.md "Worker health"). Untrusted on the coordinator's side:
// AnnouncedWorkerId makes it printable ASCII without spaces, at most kMaxAnnouncedIdBytes.
inline constexpr char kWorkerIdMetadata[] = "pf-worker-id";
inline constexpr size_t kMaxAnnouncedIdBytes = 64;
inline std::string AnnouncedWorkerId(std::string_view worker_id) {
  std::string id;
  for (const char c : worker_id.substr(0, kMaxAnnouncedIdBytes)) id += (c >= 0x21 && c <= 0x7e) ? c : '?';
  return id;
}

// `text` for a log line or an error message: non-printable bytes (\n, ESC, ...) as \xNN, cut to
// `max_bytes` with "...", in single quotes.
inline std::string Quote(std::string_view text, size_t max_bytes = kMaxEchoBytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out = "'";
  for (size_t i = 0; i < text.size() && i < max_bytes; ++i) {
    const auto u = static_cast<unsigned char>(text[i]);
    if (u < 0x20 || u >= 0x7f || text[i] == '\'' || text[i] == '\\') {
      out += "\\x";
      out += kHex[u >> 4];
      out += kHex[u & 15];
    } else {
      out += text[i];
    }
  }
  if (text.size() > max_bytes) out += "...";
  return out + "'";
}

// Free text from a request kept for display (a worker's failure reason): control and non-ASCII
// bytes as \xNN, cut to `max_bytes` of input — safe to log and to show in a terminal.
inline std::string Printable(std::string_view text, size_t max_bytes) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (size_t i = 0; i < text.size() && i < max_bytes; ++i) {
    const auto u = static_cast<unsigned char>(text[i]);
    if (u < 0x20 || u >= 0x7f) {
      out += "\\x";
      out += kHex[u >> 4];
      out += kHex[u & 15];
    } else {
      out += text[i];
    }
  }
  return out;
}

// An identifier from a request: non-empty, at most `max_bytes`, printable ASCII without spaces.
// InputError naming `field` — without echoing an over-long value.
inline void CheckId(std::string_view value, const char* field, size_t max_bytes = kMaxIdBytes) {
  if (value.empty()) throw InputError(std::string(field) + ": required");
  if (value.size() > max_bytes)
    throw InputError(std::string(field) + ": longer than " + std::to_string(max_bytes) + " bytes");
  for (const char ch : value) {
    const auto u = static_cast<unsigned char>(ch);
    if (u <= 0x20 || u >= 0x7f)
      throw InputError(std::string(field) + " " + Quote(value) + ": only printable ASCII without spaces");
  }
}

// Free text from a request (a job name): at most `max_bytes`, no control characters (they would
// forge log lines or drive terminals).
inline void CheckText(std::string_view value, const char* field, size_t max_bytes) {
  if (value.size() > max_bytes)
    throw InputError(std::string(field) + ": longer than " + std::to_string(max_bytes) + " bytes");
  for (const char ch : value) {
    const auto u = static_cast<unsigned char>(ch);
    if (u < 0x20 || u == 0x7f)
      throw InputError(std::string(field) + " " + Quote(value) + ": contains a control character");
  }
}

}  // namespace pf::limits
