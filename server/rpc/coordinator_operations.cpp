#include "server/rpc/coordinator_operations.h"

#include "proto/limits.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>

#include "common/core/error.h"
#include "common/photon/photon_maps_bytes.h"
#include "server/errors.h"
#include "server/rpc/job_images.h"
#include "server/scheduling/job_requeue.h"
#include "server/scheduling/job_submission.h"

namespace pf::server {
namespace v1 = photonfarm::v1;

Reservation CoordinatorOperations::AdmitSceneUpload(const std::string& client, uint64_t bytes) {
  return p_.admission.AdmitUpload(client, bytes);
}

UploadResult CoordinatorOperations::StoreScene(const SceneBundle& bundle, const Reservation& upload) {
  p_.admission.CheckSceneBytes(upload, [&] { return p_.scenes.FindScene(BundleHash(bundle)).has_value(); });
  return p_.scenes.Upload(bundle);
}

AdmittedJob CoordinatorOperations::AdmitJob(const v1::JobSpec& spec, const std::string& client) {
  if (!spec.requeued_from().empty())
    throw InputError(
        "spec.requeued_from: set by the coordinator for a requeued job (RequeueJob), not by a client");
  return AdmitSpec(spec, client);
}

AdmittedJob CoordinatorOperations::AdmitSpec(const v1::JobSpec& spec, const std::string& client) {
  // --plan auto without a worker count plans for the workers seen in the last minute.
  uint32_t live = 0;
  for (const v1::WorkerInfo& w : p_.scheduler.activity().Workers())
    if (w.seconds_since_seen() <= kLiveSeconds && !w.refused() && !w.offline()) ++live;
  AdmittedJob job;
  job.config = ValidateJobSpec(spec, p_.scenes, std::max(1u, live));
  // Dependencies are stored as whole ids of jobs known now (docs/farm.md "Job dependencies").
  job.config.spec.clear_after();
  for (size_t i = 0; i < job.config.after.size(); ++i) {
    std::string& id = job.config.after[i];
    // The registry's errors name job_id: named here by the field they are about.
    const auto field = [&](const std::exception& e) {
      const std::string why = e.what();
      return "spec.after[" + std::to_string(i) + "]" + why.substr(std::min(why.find(':'), why.size()));
    };
    try {
      id = p_.scheduler.ResolveJobId(id);
    } catch (const NotFoundError& e) {
      throw NotFoundError(field(e));
    } catch (const InputError& e) {  // an ambiguous prefix
      throw InputError(field(e));
    }
    if (std::count(job.config.after.begin(), job.config.after.begin() + int64_t(i), id) > 0)
      throw InputError("spec.after[" + std::to_string(i) + "]: job " + limits::Quote(id) + " is named twice");
    job.config.spec.add_after(id);
  }
  job.client = client;
  job.reservation =
      p_.admission.AdmitJob(client, ScheduledTaskCount(job.config),
                            uint64_t(job.config.camera.width) * uint64_t(job.config.image_height()));
  return job;
}

std::string CoordinatorOperations::SubmitJob(AdmittedJob job) {
  std::string id = SubmitValidatedJob(p_.scheduler, p_.db, std::move(job.config), job.client);
  job.reservation.Release();  // the scheduler counts the job now
  return id;
}

AdmittedRequeue CoordinatorOperations::AdmitRequeue(const v1::RequeueJobRequest& request,
                                                    const std::string& client) {
  AdmittedRequeue out;
  out.source = p_.scheduler.FinishedJobOf(request.job_id());
  out.job = AdmitSpec(
      RequeuedSpec(out.source, request.extend_to(), request.has_stop() ? &request.stop() : nullptr), client);
  return out;
}

v1::RequeueJobResponse CoordinatorOperations::RequeueJob(AdmittedRequeue requeue) {
  const RequeuedJob job =
      RequeueValidatedJob(p_.scheduler, p_.db, p_.persister.checkpoint_dir(), requeue.source,
                          std::move(requeue.job.config), requeue.job.client);
  requeue.job.reservation.Release();  // the scheduler counts the job now
  v1::RequeueJobResponse out;
  out.set_job_id(job.job_id);
  out.set_tasks_carried(job.tasks_carried);
  return out;
}

v1::JobStatus CoordinatorOperations::JobStatus(const std::string& job_id) {
  return p_.scheduler.Status(job_id);
}

Scheduler::JobPage CoordinatorOperations::ListJobs(bool include_finished, uint64_t after_seq, size_t limit) {
  return p_.scheduler.ListPage(include_finished, after_seq, limit);
}

v1::JobStatus CoordinatorOperations::CancelJob(const std::string& job_id) {
  return p_.scheduler.Cancel(job_id);
}

v1::JobStatus CoordinatorOperations::SetJobPaused(const std::string& job_id, bool paused) {
  v1::JobStatus status = p_.scheduler.SetPaused(job_id, paused);
  try {
    p_.db.SetJobPaused(status.job_id(), paused);  // a restarted coordinator keeps it paused
  } catch (...) {
    // Not stored: undone, so that memory and disk agree; the caller may try again (UNAVAILABLE).
    try {
      p_.scheduler.SetPaused(status.job_id(), !paused);
    } catch (const PreconditionError&) {
      // It finished meanwhile: a finished job's flag means nothing (recovery ignores it).
    }
    throw;
  }
  return status;
}

v1::DeleteJobResponse CoordinatorOperations::DeleteJob(const std::string& job_id) {
  // Checked first (NOT_FOUND, FAILED_PRECONDITION): a finished job stays finished, so the removal
  // below, after its rows are deleted, cannot be refused.
  const std::string id = p_.scheduler.CheckRemovable(job_id);
  std::shared_ptr<const JobConfig> config;
  v1::DeleteJobResponse out;
  out.set_job_id(id);
  out.set_bytes_freed(p_.persister.DeleteJob(id, [&] { config = p_.scheduler.RemoveJob(id); }));
  // Its stored maps no remaining job uses (the job is gone: JobConfigs no longer lists it).
  const DistributedMaps::Removed maps = p_.maps.RemoveMapsOf(id, *config, p_.scheduler.JobConfigs());
  out.set_bytes_freed(out.bytes_freed() + maps.bytes);
  out.set_maps_removed(maps.maps);
  spdlog::info("job {}: deleted: {} bytes freed ({} photon maps)", id, out.bytes_freed(), maps.maps);
  return out;
}

size_t CoordinatorOperations::DeleteFinishedBefore(int64_t cutoff_unix_ms) {
  size_t deleted = 0;
  for (const std::string& id : p_.scheduler.FinishedBefore(cutoff_unix_ms)) {
    try {
      DeleteJob(id);
      ++deleted;
    } catch (const NotFoundError&) {
      // deleted meanwhile (pf delete)
    } catch (const std::exception& e) {
      spdlog::warn("job {}: not deleted by --retain-finished now: {}", id, e.what());
    }
  }
  if (deleted > 0) spdlog::info("--retain-finished: {} finished jobs deleted", deleted);
  return deleted;
}

CoordinatorOperations::QuotaDeletion CoordinatorOperations::DeleteFinishedOverQuota(uint64_t bytes,
                                                                                    uint64_t target) {
  QuotaDeletion out;
  for (const std::string& id : p_.scheduler.FinishedBefore(std::numeric_limits<int64_t>::max())) {
    if (bytes <= target + out.bytes_freed) break;
    try {
      out.bytes_freed += DeleteJob(id).bytes_freed();
      ++out.jobs;
    } catch (const NotFoundError&) {
      // deleted meanwhile (pf delete)
    } catch (const std::exception& e) {
      // Kept for now (a live job names it in --after, a verification needs it): measured again
      // every 50 ms, so not a warning each time; the coordinator warns once if the quota is missed.
      spdlog::debug("job {}: not deleted by --data-quota now: {}", id, e.what());
    }
  }
  return out;
}

std::vector<v1::WorkerInfo> CoordinatorOperations::Workers() {
  return p_.scheduler.activity().Workers();
}

std::vector<v1::TaskEvent> CoordinatorOperations::JobEvents(const std::string& job_id, uint64_t* dropped) {
  // NotFoundError for an unknown job; the whole id of a prefix.
  const std::string id = p_.scheduler.Status(job_id).job_id();
  return p_.scheduler.activity().Events(id, dropped);
}

ResolvedImage CoordinatorOperations::JobImage(const std::string& job_id, v1::JobStatus* status) {
  return ResolveJobImage(p_.scheduler, job_id, status);
}

std::optional<std::string> CoordinatorOperations::WorkerSeen(const WorkerHello& hello) {
  // The coordinator's own version string is taken as it is; any other must be printable ASCII
  // without spaces, as an id: it is logged and listed (pf workers, the web page).
  if (hello.version != p_.build_version) {
    if (!hello.version.empty()) limits::CheckId(hello.version, "worker_version", limits::kMaxIdBytes);
    if (!p_.allow_mixed_versions) {
      // Farms run one build (docs/farm.md, "Upgrades"): another build may trace other photons or
      // estimate differently, and a job's image would mix the two. Listed as refused (never as an
      // idle worker of the farm) so that pf workers and the web page say why.
      const std::string worker_build =
          hello.version.empty() ? "none (older than the check)" : limits::Quote(hello.version);
      p_.scheduler.activity().WorkerSeen(hello.worker_id, hello.peer, hello.threads, hello.version,
                                         "another build: " + worker_build);
      spdlog::warn("worker {} refused: its build {} is not the coordinator's '{}'",
                   limits::Quote(hello.worker_id), worker_build, p_.build_version);
      return "worker_version: this worker's build is " + worker_build + ", the coordinator's '" +
             p_.build_version +
             "'; farms run one build (docs/farm.md, Upgrades): run workers of the coordinator's build, or "
             "start "
             "the coordinator with --allow-mixed-versions";
    }
  }
  p_.scheduler.activity().WorkerSeen(hello.worker_id, hello.peer, hello.threads, hello.version);
  return std::nullopt;
}

uint64_t CoordinatorOperations::LeaseOrWait(const LeaseRequest& request, double wait_seconds,
                                            std::function<void(std::optional<Lease>)> done) {
  return p_.scheduler.LeaseOrWait(request, wait_seconds, std::move(done));
}

void CoordinatorOperations::CancelWait(uint64_t waiter) {
  p_.scheduler.CancelWait(waiter);
}

void CoordinatorOperations::WorkerLeft(const std::string& worker_id) {
  p_.scheduler.WorkerLeft(worker_id);
}

void CoordinatorOperations::ReturnLease(const std::string& lease_id) {
  p_.scheduler.ReturnLease(lease_id);
}

std::optional<BuiltMap> CoordinatorOperations::MapFor(const std::string& job_id, uint64_t map_index) {
  return p_.maps.MapFor(job_id, map_index);
}

ExtendResult CoordinatorOperations::ExtendLease(const std::string& lease_id, const std::string& worker_id,
                                                double progress) {
  // Render tasks and map pieces alike: the scheduler's lease table knows the lease's kind.
  return p_.scheduler.Extend(lease_id, worker_id, progress);
}

CompleteResult CoordinatorOperations::CompleteTask(const std::string& lease_id, const std::string& worker_id,
                                                   std::span<const float> rgb_sums, RadiancePart part,
                                                   const TaskStats& stats) {
  CompleteResult result = p_.scheduler.Complete(lease_id, worker_id, rgb_sums, part);
  if (result.status == CompleteStatus::kMerged)
    p_.scheduler.activity().WorkerStats(result.worker_id, stats.photons_emitted, stats.seconds);
  return result;
}

void CoordinatorOperations::AcknowledgeWhenStored(const CompleteResult& merged,
                                                  std::span<const float> rgb_sums,
                                                  std::function<void(const std::string& not_stored)> answer) {
  if (!p_.persister.durable_acks()) {
    answer("");
    return;
  }
  // Not stored: the result is in this coordinator's memory and stored when the disk allows, or
  // re-run after a restart (never counted twice); the worker must not count it as merged.
  p_.persister.JournalThenAck(merged.job_id, merged.task_id, merged.epoch, merged.merge_seq, rgb_sums,
                              [answer = std::move(answer), job = merged.job_id,
                               task = merged.task_id](const std::string& not_stored) {
                                if (!not_stored.empty())
                                  spdlog::warn(
                                      "job {} task {}: result merged but not stored ({}): not acknowledged",
                                      job, task, not_stored);
                                answer(not_stored);
                              });
}

FailOutcome CoordinatorOperations::FailTask(const std::string& lease_id, const std::string& worker_id,
                                            const std::string& reason, bool retryable) {
  return p_.scheduler.Fail(lease_id, worker_id, reason, retryable);
}

std::vector<std::pair<std::string, std::filesystem::path>> CoordinatorOperations::SceneFiles(
    const std::string& scene_hash) {
  return p_.scenes.ListFiles(scene_hash);
}

DistributedMaps::UploadAdmission CoordinatorOperations::BeginPieceUpload(const std::string& lease_id,
                                                                         const std::string& worker_id) {
  return p_.maps.BeginUpload(lease_id, worker_id);
}

void CoordinatorOperations::EndPieceUpload(const std::string& lease_id) {
  p_.maps.EndUpload(lease_id);
}

DistributedMaps::Accepted CoordinatorOperations::AcceptPiece(const std::string& lease_id,
                                                             const std::string& worker_id,
                                                             const std::string& bytes) {
  return p_.maps.AcceptChunk(lease_id, worker_id, bytes);
}

BuiltMapFile CoordinatorOperations::MapFile(const std::string& map_key) {
  const std::optional<std::filesystem::path> file = p_.maps.MapFile(map_key);
  if (!file) throw NotFoundError("map_key: no built map " + map_key);
  try {
    return {*file, PhotonMapsFileDigest(*file)};
  } catch (const InputError& e) {
    // The coordinator's own file, not the worker's input.
    throw DataLossError("map_key: the built map " + map_key + " is damaged: " + e.what());
  }
}

}  // namespace pf::server
