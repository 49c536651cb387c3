// pf's farm commands: submit, watch, get, list, cancel (to a running coordinator) and
// `render --workers N` (a coordinator and N workers started, watched and stopped by pf).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <mutex>
#include <nlohmann/json.hpp>
#include <thread>

#include "client/commands.h"
#include "client/farm_client.h"
#include "client/frame_files.h"
#include "client/interrupt.h"
#include "client/local_farm.h"
#include "client/progress.h"
#include "common/core/atomic_file.h"
#include "common/core/duration_text.h"
#include "common/core/error.h"
#include "common/image/exr_io.h"
#include "proto/convert.h"
#include "rpc/address.h"

namespace pf {
namespace v1 = photonfarm::v1;

namespace {

std::string CoordinatorAddress(const FarmArgs& f) {
  if (!f.coordinator.empty()) return f.coordinator;
  const char* env = std::getenv("PF_COORDINATOR");
  if (env && *env) {
    if (const std::string problem = CoordinatorAddressProblem(env); !problem.empty())
      throw InputError("PF_COORDINATOR: " + problem);
    return env;
  }
  throw InputError("--coordinator: required (HOST:PORT, or set PF_COORDINATOR)");
}

FarmClient Connect(const FarmArgs& f) {
  return FarmClient(CoordinatorAddress(f), ResolveToken(f.token_file), f.timeout,
                    ResolveClientTls(f.tls_ca, f.tls_cert, f.tls_key));
}

// The job's plan as the coordinator stores it (for --plan auto: the chosen one).
std::string PlanText(const v1::JobStatus& s) {
  try {
    return DescribePlan(PlanFromProto(s.spec().plan(), "spec.plan"));
  } catch (const InputError&) {
    return "unknown";
  }
}

// The state a person reads: "paused" for a queued or running job a user paused (pf pause),
// "waiting" for a queued one whose dependencies have not succeeded yet (pf submit --after).
const char* StateText(const v1::JobStatus& s) {
  if (s.paused()) return "paused";
  return s.waiting_for_size() > 0 ? "waiting" : JobStateName(s.state());
}

nlohmann::json StatusJson(const v1::JobStatus& s) {
  nlohmann::json blocklisted = nlohmann::json::array();
  for (const v1::BlocklistedWorker& b : s.blocklisted_workers())
    blocklisted.push_back({{"worker_id", b.worker_id()},
                           {"failed_attempts", b.failed_attempts()},
                           {"last_error", b.last_error()}});
  // What each `auto` setting became and why (pf's integrator, the coordinator's choices).
  nlohmann::json auto_settings = nlohmann::json::array();
  for (const v1::AutoSetting& a : s.spec().auto_settings())
    auto_settings.push_back({{"setting", a.setting()}, {"value", a.value()}, {"reason", a.reason()}});
  return {{"job_id", s.job_id()},
          {"name", s.spec().name()},
          {"state", JobStateName(s.state())},
          {"failure_reason", s.failure_reason()},
          {"tasks_total", s.tasks_total()},
          {"tasks_done", s.tasks_done()},
          {"tasks_running", s.tasks_running()},
          {"samples_merged", s.samples_merged()},
          {"elapsed_seconds", s.elapsed_seconds()},
          {"eta_seconds", s.eta_seconds()},
          {"estimated_noise_rms", s.estimated_noise_rms()},
          {"estimated_bias_rms", s.estimated_bias_rms()},
          {"estimated_error_rms", s.estimated_error_rms()},
          {"target_missed", s.target_missed()},
          {"rounds_done", s.rounds_done()},
          {"priority", s.spec().priority()},
          {"submitted_unix_ms", s.submitted_unix_ms()},
          {"plan", PlanText(s)},
          {"plan_auto_reason", s.spec().plan().chosen_by_auto().reason()},
          {"auto_settings", auto_settings},
          {"requeued_from", s.spec().requeued_from()},
          {"waiting_for", std::vector<std::string>(s.waiting_for().begin(), s.waiting_for().end())},
          {"blocklisted_workers", blocklisted},
          {"storage_error", s.storage_error()},
          {"paused_for_storage", s.paused_for_storage()},
          {"paused", s.paused()},
          {"verifications_pending", s.verifications_pending()},
          {"results_verified", s.results_verified()}};
}

std::string Summary(const v1::JobStatus& s) {
  std::string out =
      fmt::format("job {} {}: {}/{} tasks, {} samples, {}", s.job_id(), StateText(s), s.tasks_done(),
                  s.tasks_total(), s.samples_merged(), FormatDuration(s.elapsed_seconds()));
  if (s.estimated_noise_rms() >= 0) out += fmt::format(", estimated noise {:.4g}", s.estimated_noise_rms());
  // The progressive plan's display-referred error and its bias part (docs/renderer.md).
  if (s.estimated_error_rms() >= 0)
    out += fmt::format(", estimated error {:.4g} (bias {:.4g})", s.estimated_error_rms(),
                       s.estimated_bias_rms());
  if (!s.target_missed().empty())
    out += "; target not met: " + s.target_missed() + " (pf requeue " + s.job_id() + " continues it)";
  if (!s.failure_reason().empty()) out += ": " + s.failure_reason();
  // Result verification (docs/farm.md): the job succeeds once its pending verifications are done.
  if (s.results_verified() > 0 || s.verifications_pending() > 0)
    out += fmt::format(", {} results verified", s.results_verified()) +
           (s.verifications_pending() > 0 ? fmt::format(" ({} pending)", s.verifications_pending()) : "");
  // The coordinator's disk is full or failing (docs/farm.md "Durability"): it retries.
  if (!s.storage_error().empty())
    out += std::string(s.paused_for_storage() ? "; PAUSED, " : "; ") + "storage: " + s.storage_error();
  out += "; plan " + PlanText(s);
  if (s.spec().plan().has_chosen_by_auto())
    out += " (auto: " + s.spec().plan().chosen_by_auto().reason() + ")";
  for (int i = 0; i < s.spec().auto_settings_size(); ++i)
    out += fmt::format("{} {} {}", i == 0 ? "; auto:" : ",", s.spec().auto_settings(i).setting(),
                       s.spec().auto_settings(i).value());
  if (!s.spec().requeued_from().empty()) out += "; requeued from " + s.spec().requeued_from();
  for (int i = 0; i < s.waiting_for_size(); ++i) out += (i == 0 ? "; waiting for " : ", ") + s.waiting_for(i);
  // Workers that get none of this job's work any more (docs/farm.md, "Worker health").
  for (int i = 0; i < s.blocklisted_workers_size(); ++i) {
    const v1::BlocklistedWorker& b = s.blocklisted_workers(i);
    out += fmt::format("{} {} ({} failed attempts)", i == 0 ? "; blocklisted:" : ",", b.worker_id(),
                       b.failed_attempts());
  }
  return out;
}

int ExitCodeForState(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED ? kExitOk : kExitFailure;
}

// Uploads the bundle and submits; returns the job id.
std::string UploadAndSubmit(FarmClient& client, PreparedJob& job) {
  const v1::UploadSceneResponse up = client.UploadScene(job.bundle);
  if (job.scene.warnings.empty())  // else PrepareJob has shown them already
    for (const std::string& w : up.warnings()) spdlog::warn("scene: {}", w);
  spdlog::info("scene {} uploaded: {} files, {} triangles, {} lights", up.scene_hash().substr(0, 12),
               job.bundle.files.size(), up.triangles(), up.lights());
  job.spec.set_scene_hash(up.scene_hash());
  return client.SubmitJob(job.spec);
}

// Watches a job, drawing progress. With `output`, the EXR is rewritten atomically as the image
// improves: from the stream's snapshots (`snapshot_every` = 0: every update carries one), or
// with GetImage at most every `snapshot_every` seconds while the stream carries status only —
// cheaper for the coordinator, and the updates can then come often (`interval`) so that the end
// of the job is seen at once. Returns the final status.
v1::JobStatus WatchWithProgress(FarmClient& client, const std::string& job_id, const std::string& output,
                                double interval, bool json, bool quiet, double snapshot_every = 0,
                                bool hint_no_workers = false) {
  FarmProgress progress(!quiet && !json);
  bool hinted = !hint_no_workers;
  const bool stream_images = !output.empty() && snapshot_every <= 0;
  auto last_snapshot = std::chrono::steady_clock::now();
  uint64_t snapshot_tasks = 0;
  const v1::JobStatus final_status =
      client.Watch(job_id, stream_images, interval, [&](const v1::JobUpdate& u) {
        progress.Update(u.status());
        if (!hinted && u.status().state() == v1::JOB_STATE_QUEUED && u.status().tasks_running() == 0) {
          hinted = true;
          try {
            const std::vector<v1::WorkerInfo> workers = client.ListWorkers();
            const bool any_usable = std::any_of(workers.begin(), workers.end(),
                                                [](const v1::WorkerInfo& w) { return !w.refused(); });
            if (workers.empty())
              spdlog::warn(
                  "no worker has contacted the coordinator yet, so the job waits (ETA unknown): start one "
                  "with "
                  "pf-worker --coordinator HOST:PORT");
            else if (!any_usable)
              spdlog::warn(
                  "the coordinator refused every worker that contacted it (another build: see pf workers), "
                  "so the job waits: start workers of the coordinator's build (docs/farm.md, Upgrades)");
          } catch (const RpcError&) {  // an older coordinator without ListWorkers: no hint
          }
        }
        if (json) {
          nlohmann::json j = StatusJson(u.status());
          j["snapshot"] = u.has_image() && !u.image().exr_bytes().empty();
          std::printf("%s\n", j.dump().c_str());
          std::fflush(stdout);
        }
        if (output.empty()) return;
        if (stream_images) {
          if (u.has_image() && !u.image().exr_bytes().empty())
            WriteJobImage(output, u.image().exr_bytes(), u.status().spec());
          return;
        }
        const auto now = std::chrono::steady_clock::now();
        if (u.status().tasks_done() > snapshot_tasks && !IsFinalState(u.status().state()) &&
            now - last_snapshot >= Seconds(snapshot_every)) {
          WriteJobImage(output, client.GetImage(job_id), u.status().spec());
          snapshot_tasks = u.status().tasks_done();
          last_snapshot = now;
        }
      });
  progress.Finish();
  return final_status;
}

}  // namespace

int ExitCodeFor(const std::exception& e) {
  if (const auto* rpc = dynamic_cast<const RpcError*>(&e)) {
    switch (rpc->code()) {
      case grpc::StatusCode::INVALID_ARGUMENT:
      case grpc::StatusCode::NOT_FOUND:
      case grpc::StatusCode::RESOURCE_EXHAUSTED:
      case grpc::StatusCode::OUT_OF_RANGE:
        return kExitBadInput;
      case grpc::StatusCode::CANCELLED:
        return Interrupted() ? kExitInterrupted : kExitFailure;
      default:
        return kExitFailure;
    }
  }
  if (dynamic_cast<const InputError*>(&e)) return kExitBadInput;
  return kExitFailure;
}

int RunSubmit(const RenderArgs& a, const FarmArgs& f) {
  PreparedJob job = PrepareJob(a);
  FarmClient client = Connect(f);
  const std::string id = UploadAndSubmit(client, job);
  std::printf("%s\n", id.c_str());
  return kExitOk;
}

int RunWatch(const FarmArgs& f, const std::string& job_id, const std::string& output, double interval,
             bool json, bool quiet) {
  if (!output.empty()) CheckWritable(output, "-o");
  FarmClient client = Connect(f);
  // An animation's frames go to a pattern: a bad one is said now, not when the first image arrives.
  if (!output.empty() && IsAnimation(client.GetJob(job_id).spec())) FramePattern(output, "-o");
  SetInterruptHandler([&client](int) { client.Cancel(); });
  v1::JobStatus st;
  try {
    st = WatchWithProgress(client, job_id, output, interval, json, quiet, 0, /*hint_no_workers=*/true);
  } catch (...) {
    SetInterruptHandler({});
    throw;
  }
  SetInterruptHandler({});
  std::string written;
  if (!output.empty()) {
    uint64_t samples = 0;
    written = WriteJobImage(output, client.GetImage(job_id, &samples), st.spec());
  }
  if (!json) std::printf("%s%s\n", Summary(st).c_str(), written.empty() ? "" : (" -> " + written).c_str());
  return ExitCodeForState(st.state());
}

int RunGet(const FarmArgs& f, const std::string& job_id, const std::string& output, const std::string& png) {
  CheckWritable(output, "-o");
  if (!png.empty()) CheckWritable(png, "--png");
  FarmClient client = Connect(f);
  uint64_t samples = 0;
  const v1::JobSpec spec = client.GetJob(job_id).spec();
  if (IsAnimation(spec) && !png.empty())
    throw InputError("--png: an animation is written as one EXR per frame, without previews");
  if (IsAnimation(spec)) FramePattern(output, "-o");
  const std::string bytes = client.GetImage(job_id, &samples);
  const std::string written = WriteJobImage(output, bytes, spec);
  if (!png.empty()) WritePreviewFor(output, png, false, DecodeExrFromMemory(bytes));
  std::printf("job %s: %zu bytes, %llu samples merged -> %s\n", job_id.c_str(), bytes.size(),
              (unsigned long long)samples, written.c_str());
  return kExitOk;
}

int RunList(const FarmArgs& f, bool all, bool json) {
  FarmClient client = Connect(f);
  const std::vector<v1::JobStatus> jobs = client.ListJobs(all);
  if (json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const v1::JobStatus& s : jobs) arr.push_back(StatusJson(s));
    std::printf("%s\n", arr.dump(2).c_str());
    return kExitOk;
  }
  std::printf("%-14s %-10s %8s %12s %10s %10s  %s\n", "JOB", "STATE", "PRIORITY", "TASKS", "ELAPSED", "NOISE",
              "NAME");
  for (const v1::JobStatus& s : jobs)
    std::printf("%-14s %-10s %8d %12s %10s %10s  %s\n", s.job_id().c_str(), StateText(s), s.spec().priority(),
                fmt::format("{}/{}", s.tasks_done(), s.tasks_total()).c_str(),
                FormatDuration(s.elapsed_seconds()).c_str(),
                s.estimated_noise_rms() >= 0 ? fmt::format("{:.4g}", s.estimated_noise_rms()).c_str() : "-",
                s.spec().name().c_str());
  return kExitOk;
}

int RunCancel(const FarmArgs& f, const std::string& job_id) {
  FarmClient client = Connect(f);
  const v1::JobStatus s = client.CancelJob(job_id);
  std::printf("%s\n", Summary(s).c_str());
  return kExitOk;
}

int RunRequeue(const FarmArgs& f, const RequeueArgs& r) {
  FarmClient client = Connect(f);
  const v1::JobStatus before = client.GetJob(r.job_id);
  v1::RequeueJobRequest request;
  request.set_job_id(before.job_id());
  if (!r.length_flag.empty()) {
    const v1::Plan& plan = before.spec().plan();
    const char* flag = plan.has_progressive()     ? "--passes"
                       : plan.has_multiple_maps() ? "--maps"
                       : plan.has_skipping()      ? "--rounds"
                                                  : "";
    if (r.length_flag != flag)
      throw InputError(
          r.length_flag + ": job " + before.job_id() + "'s plan has " +
          (*flag ? std::string(flag + 2) + " (give " + flag + ")" : std::string("no length to extend")));
    request.set_extend_to(r.length);
  }
  if (r.time_budget >= 0 || r.target_noise >= 0 || r.target_error >= 0) {
    v1::StopRule& stop = *request.mutable_stop();
    stop = before.spec().stop();
    if (r.time_budget >= 0) stop.set_time_budget_seconds(r.time_budget);
    if (r.target_noise >= 0) stop.set_target_noise_rms(r.target_noise);
    if (r.target_error >= 0) stop.set_target_error_rms(r.target_error);
  }
  // A job that has just ended may still be writing its final results: tried again for 30 s.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  v1::RequeueJobResponse out;
  for (;;) {
    try {
      out = client.RequeueJob(request);
      break;
    } catch (const RpcError& e) {
      if (e.code() != grpc::StatusCode::UNAVAILABLE || std::chrono::steady_clock::now() > give_up ||
          std::string(e.what()).find("still being written") == std::string::npos)
        throw;
      std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
  }
  spdlog::info("job {} ({}) requeued as job {}: {} merged tasks carried", before.job_id(),
               JobStateName(before.state()), out.job_id(), out.tasks_carried());
  std::printf("%s\n", out.job_id().c_str());
  return kExitOk;
}

int RunPause(const FarmArgs& f, const std::string& job_id, bool paused) {
  FarmClient client = Connect(f);
  const v1::JobStatus s = client.SetJobPaused(job_id, paused);
  std::printf("%s\n", Summary(s).c_str());
  return kExitOk;
}

namespace {

std::string Bytes(uint64_t bytes) {
  if (bytes < 1024) return fmt::format("{} B", bytes);
  if (bytes < (uint64_t(1) << 20)) return fmt::format("{:.1f} KiB", double(bytes) / 1024);
  if (bytes < (uint64_t(1) << 30)) return fmt::format("{:.1f} MiB", double(bytes) / double(1 << 20));
  return fmt::format("{:.2f} GiB", double(bytes) / double(1 << 30));
}

std::string DeletedLine(const v1::DeleteJobResponse& d) {
  return fmt::format("deleted {}: {} freed{}", d.job_id(), Bytes(d.bytes_freed()),
                     d.maps_removed() > 0 ? fmt::format(" ({} photon maps)", d.maps_removed()) : "");
}

}  // namespace

int RunDelete(const FarmArgs& f, const std::vector<std::string>& job_ids) {
  FarmClient client = Connect(f);
  int code = kExitOk;
  for (const std::string& id : job_ids) {
    try {
      std::printf("%s\n", DeletedLine(client.DeleteJob(id)).c_str());
    } catch (const RpcError& e) {
      spdlog::error("{}: {}", id, e.what());
      code = ExitCodeFor(e);
    }
  }
  return code;
}

int RunPurge(const FarmArgs& f, double older_than_seconds, bool dry_run) {
  FarmClient client = Connect(f);
  const int64_t now_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
  const int64_t cutoff_ms = now_ms - int64_t(older_than_seconds * 1000.0);
  int code = kExitOk;
  uint64_t jobs = 0, bytes = 0;
  for (const v1::JobStatus& s : client.ListJobs(/*include_finished=*/true)) {
    if (!IsFinalState(s.state()) || s.finished_unix_ms() <= 0 || s.finished_unix_ms() > cutoff_ms) continue;
    const std::string age = FormatDuration(double(now_ms - s.finished_unix_ms()) / 1000.0);
    if (dry_run) {
      std::printf("would delete %s %s (%s, finished %s ago)\n", s.job_id().c_str(), JobStateName(s.state()),
                  s.spec().name().c_str(), age.c_str());
      ++jobs;
      continue;
    }
    try {
      const v1::DeleteJobResponse d = client.DeleteJob(s.job_id());
      std::printf("%s (%s, %s, finished %s ago)\n", DeletedLine(d).c_str(), JobStateName(s.state()),
                  s.spec().name().c_str(), age.c_str());
      ++jobs;
      bytes += d.bytes_freed();
    } catch (const RpcError& e) {
      if (e.code() == grpc::StatusCode::NOT_FOUND) continue;  // deleted meanwhile by someone else
      spdlog::error("{}: {}", s.job_id(), e.what());
      code = ExitCodeFor(e);
    }
  }
  if (dry_run)
    std::printf("%lu jobs would be deleted\n", static_cast<unsigned long>(jobs));
  else
    std::printf("purged %lu jobs, %s freed\n", static_cast<unsigned long>(jobs), Bytes(bytes).c_str());
  return code;
}

int RunWorkers(const FarmArgs& f, bool json) {
  FarmClient client = Connect(f);
  const std::vector<v1::WorkerInfo> workers = client.ListWorkers();
  if (json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const v1::WorkerInfo& w : workers)
      arr.push_back({{"worker_id", w.worker_id()},
                     {"peer", w.peer()},
                     {"threads", w.threads()},
                     {"busy", w.busy()},
                     {"current_job_id", w.current_job_id()},
                     {"current_task_id", w.current_task_id()},
                     {"tasks_done", w.tasks_done()},
                     {"tasks_failed", w.tasks_failed()},
                     {"photons_emitted", w.photons_emitted()},
                     {"busy_seconds", w.busy_seconds()},
                     {"photons_per_second", w.photons_per_second()},
                     {"seconds_since_seen", w.seconds_since_seen()},
                     {"version", w.version()},
                     {"refused", w.refused()},
                     {"refused_reason", w.refused_reason()},
                     {"refused_calls", w.refused_calls()},
                     {"lost", w.lost()},
                     {"offline", w.offline()},
                     {"quarantined", w.quarantined()},
                     {"quarantine_reason", w.quarantine_reason()},
                     {"quarantine_seconds_left", w.quarantine_seconds_left()},
                     {"blocklisted_job_ids", w.blocklisted_job_ids()}});
    std::printf("%s\n", arr.dump(2).c_str());
    return kExitOk;
  }
  if (workers.empty()) {
    std::printf("no workers have contacted this coordinator\n");
    return kExitOk;
  }
  std::printf("%-24s %-22s %7s %-20s %6s %6s %12s %10s  %s\n", "WORKER", "PEER", "THREADS", "CURRENT", "DONE",
              "FAILED", "PHOTONS/S", "SEEN", "BUILD");
  for (const v1::WorkerInfo& w : workers) {
    // Worker health (docs/farm.md): quarantined and lost workers say so where the task would be.
    const std::string current =
        w.refused()       ? "refused"
        : w.quarantined() ? "quarantined " + FormatDuration(w.quarantine_seconds_left())
        : w.offline()     ? "offline"
        : w.lost()        ? "lost"
        : w.busy()        ? fmt::format("{} task {}", w.current_job_id(), w.current_task_id())
                          : "idle";
    std::printf("%-24s %-22s %7u %-20s %6llu %6llu %12.4g %10s  %s\n", w.worker_id().c_str(),
                w.peer().empty() ? "-" : w.peer().c_str(), w.threads(), current.c_str(),
                (unsigned long long)w.tasks_done(), (unsigned long long)w.tasks_failed(),
                w.photons_per_second(), (FormatDuration(w.seconds_since_seen()) + " ago").c_str(),
                w.version().c_str());
    if (w.refused())
      std::printf("  refused: %s (%llu calls)\n", w.refused_reason().c_str(),
                  (unsigned long long)w.refused_calls());
    if (w.quarantined()) std::printf("  quarantined: %s\n", w.quarantine_reason().c_str());
    if (w.blocklisted_job_ids_size() > 0) {
      std::string jobs;
      for (const std::string& id : w.blocklisted_job_ids()) jobs += (jobs.empty() ? "" : ", ") + id;
      std::printf("  blocklisted for: %s\n", jobs.c_str());
    }
  }
  return kExitOk;
}

int RunEvents(const FarmArgs& f, const std::string& job_id, bool json) {
  FarmClient client = Connect(f);
  const v1::ListJobEventsResponse r = client.ListJobEvents(job_id);
  if (json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const v1::TaskEvent& e : r.events())
      arr.push_back({{"unix_ms", e.unix_ms()},
                     {"kind", e.kind()},
                     {"task_id", e.task_id()},
                     {"attempt", e.attempt()},
                     {"worker_id", e.worker_id()},
                     {"detail", e.detail()}});
    std::printf(
        "%s\n",
        nlohmann::json{{"job_id", job_id}, {"dropped", r.dropped()}, {"events", arr}}.dump(2).c_str());
    return kExitOk;
  }
  if (r.dropped() > 0) std::printf("(%llu older events not kept)\n", (unsigned long long)r.dropped());
  std::printf("%-23s %-9s %6s %7s %-24s %s\n", "TIME (UTC)", "EVENT", "TASK", "ATTEMPT", "WORKER", "DETAIL");
  for (const v1::TaskEvent& e : r.events()) {
    const std::time_t t = std::time_t(e.unix_ms() / 1000);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char when[32];
    std::strftime(when, sizeof(when), "%Y-%m-%d %H:%M:%S", &tm);
    std::printf("%s.%03d %-9s %6llu %7u %-24s %s\n", when, int(e.unix_ms() % 1000), e.kind().c_str(),
                (unsigned long long)e.task_id(), e.attempt(), e.worker_id().c_str(), e.detail().c_str());
  }
  return kExitOk;
}

int RunFarmRender(const RenderArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  // Everything that can be wrong with the input is found before a process starts.
  PreparedJob job = PrepareJob(a);
  const std::string output =
      a.output.empty() ? std::filesystem::path(a.scene).stem().string() + ".exr" : a.output;
  CheckWritable(output, "-o");
  if (!a.frames.empty()) FramePattern(output, "-o");  // before a process starts
  if (!a.png.empty()) CheckWritable(a.png, "--png");

  LocalFarmOptions fo;
  fo.workers = a.workers;
  fo.threads_per_worker =
      a.threads > 0 ? a.threads
                    : std::max(1, int(std::thread::hardware_concurrency()) / std::max(1, a.workers));
  fo.coordinator_bin = a.coordinator_bin;
  fo.worker_bin = a.worker_bin;
  fo.coordinator_args = a.coordinator_args;
  fo.worker_args = a.worker_args;
  fo.keep_dir = a.keep_farm_dir;
  fo.log_level = spdlog::get_level() <= spdlog::level::debug ? "debug" : "info";
  LocalFarm farm(fo);  // forks before any gRPC channel exists in this process
  spdlog::info("local farm: coordinator {} and {} workers x {} threads (logs in {})", farm.address(),
               a.workers, fo.threads_per_worker, farm.dir().string());
  auto client_ptr = std::make_unique<FarmClient>(farm.address(), farm.token(), 60);
  FarmClient& client = *client_ptr;

  // Ctrl-C: cancel the watch and stop the children (a second Ctrl-C kills them).
  SetInterruptHandler([&](int n) {
    client.Cancel();
    if (n == 1)
      farm.TerminateAll();
    else
      farm.KillNow();
  });
  // A dead coordinator, or no worker left, would leave the watch waiting forever.
  std::mutex monitor_mutex;
  std::condition_variable monitor_cv;
  bool monitor_stop = false;
  std::string farm_error;
  std::thread monitor([&] {
    std::unique_lock lock(monitor_mutex);
    while (!monitor_cv.wait_for(lock, std::chrono::milliseconds(200), [&] { return monitor_stop; })) {
      const std::string dead = farm.CheckChildren();
      if (dead.empty()) continue;
      spdlog::warn("{}", dead);
      if (!farm.coordinator_alive() || farm.live_workers() == 0) {
        farm_error = dead;
        client.Cancel();
        return;
      }
    }
  });
  auto cleanup = [&](bool keep_logs) {
    {
      std::lock_guard lock(monitor_mutex);
      monitor_stop = true;
    }
    monitor_cv.notify_all();
    if (monitor.joinable()) monitor.join();
    SetInterruptHandler([&](int n) {
      if (n == 1)
        farm.TerminateAll();
      else
        farm.KillNow();
    });
    client_ptr.reset();  // close the connection first: the coordinator then stops at once
    farm.Shutdown(10, keep_logs);
    SetInterruptHandler({});
  };

  v1::JobStatus st;
  std::string bytes;
  try {
    const std::string id = UploadAndSubmit(client, job);
    spdlog::info("job {} submitted ({} workers)", id, a.workers);
    // Status every 0.1 s at most (the end is seen at once); the output EXR is refreshed every 2 s
    // with GetImage — each snapshot costs the coordinator an EXR encoding, on the same cores.
    st = WatchWithProgress(client, id, output, 0.1, false, a.quiet, 2.0);
    if (st.state() == v1::JOB_STATE_SUCCEEDED) bytes = client.GetImage(id);
  } catch (const std::exception& e) {
    const bool interrupted = Interrupted();
    // Keep the farm's logs when the farm itself failed, not for a request it rightly rejected.
    cleanup(!interrupted && ExitCodeFor(e) != kExitBadInput);
    if (interrupted) {
      std::fprintf(stderr, "\ninterrupted: the farm was shut down\n");
      return kExitInterrupted;
    }
    if (!farm_error.empty()) throw SystemError("the local farm broke: " + farm_error);
    throw;
  }
  if (st.state() != v1::JOB_STATE_SUCCEEDED) {
    cleanup(true);
    spdlog::error("{}", Summary(st));
    return kExitFailure;
  }
  cleanup(false);

  // The coordinator's header says what the image is of, as pf render's does (docs/farm.md, "Image
  // headers"): kept as it is; pf adds how it was made.
  ImageMetadata meta;
  Image image = DecodeExrFromMemory(bytes, &meta);
  meta["farm.workers"] = std::to_string(a.workers);
  meta["farm.job_id"] = st.job_id();
  meta["tasks"] = std::to_string(st.tasks_done());
  meta["samples_merged"] = std::to_string(st.samples_merged());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  meta["render_seconds"] = fmt::format("{:.3f}", seconds);
  AddProvenance(meta);
  std::string written = output;
  if (IsAnimation(st.spec())) {
    const std::vector<std::string> paths =
        WriteFrameFiles(FramePattern(output, "-o"), bytes, st.spec(), meta);
    written = paths.front() + " .. " + paths.back() + " (" + std::to_string(paths.size()) + " frames)";
  } else {
    WriteExr(output, image, meta);
    WritePreviewFor(output, a.png, a.no_png, image);
  }
  std::printf("rendered %dx%d on %d workers, %s, %llu tasks in %.2f s -> %s\n", image.width(),
              int(st.spec().camera().height()), a.workers,
              DescribePlan(PlanFromProto(st.spec().plan(), "spec.plan")).c_str(),
              (unsigned long long)st.tasks_done(), seconds, written.c_str());
  return kExitOk;
}

}  // namespace pf
