#include "server/rpc/job_images.h"

#include <fmt/format.h>

#include <ctime>

#include "common/core/error.h"
#include "common/plan/render_header.h"
#include "photonfarm_version.h"
#include "proto/convert.h"
#include "server/assembly/image_snapshot.h"
#include "server/errors.h"
#include "server/store/checkpoint.h"

namespace pf::server {
namespace {

// What the image is of, in the keys and values pf render writes (common/plan/render_header.h,
// docs/farm.md "Image headers"), so that `pf info x.exr` and `pf merge` can tell; then the job's
// name and state, the build and the date.
void AddJobMetadata(const photonfarm::v1::JobStatus& status, const JobConfig& config, ImageMetadata& meta) {
  namespace v1 = photonfarm::v1;
  // The config's settings are the spec's as echoed: resolved at submission (job_spec.cpp).
  RecordRender({.scene = config.scene_entry,
                .scene_hash = config.scene_hash,
                .camera = config.camera,
                .settings = config.settings,
                .plan = config.plan,
                .seed = config.seed,
                .auto_choices = AutoChoicesFromProto(config.spec.auto_settings(), "spec.auto_settings")},
               meta);
  // An animation's image is its frames stacked (frame_tasks.h); pf writes each frame to a file of
  // its own with its camera and number (client/frame_files.h).
  if (!config.frames.empty())
    meta["animation.frames"] = std::to_string(config.first_frame) + "-" +
                               std::to_string(uint64_t(config.first_frame) + config.frames.size() - 1);
  meta["job_name"] = config.name;
  meta["job_state"] = v1::JobState_Name(status.state());
  meta["version"] = PF_VERSION;
  // The job's submission time, not "now": the same merged state encodes to the same bytes.
  const std::time_t submitted = std::time_t(status.submitted_unix_ms() / 1000);
  std::tm tm{};
  gmtime_r(&submitted, &tm);
  char date[32];
  std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", &tm);
  meta["date"] = date;
}

}  // namespace

ResolvedImage ResolveJobImage(Scheduler& scheduler, const std::string& requested_id,
                              photonfarm::v1::JobStatus* status) {
  JobSnapshot snap = scheduler.Snapshot(requested_id, /*with_image=*/true);
  const std::string job_id = snap.status.job_id();  // the whole id of a prefix (JobRegistry::Resolve)
  ResolvedImage image;
  if (snap.image) {
    image = std::move(*snap.image);
  } else {
    // A finished job's image lives only in its checkpoint, served only if the file carries the
    // seal stored with the job (docs/farm.md "Durability"): a damaged, missing, foreign or older
    // file means acknowledged results are lost (DATA_LOSS, no server path in the message).
    std::optional<Checkpoint> cp;
    std::optional<Accumulator> stored;
    bool unreadable = false;
    const std::string problem =
        VerifyCheckpointFile(snap.checkpoint_path, snap.checkpoint_seal, &cp, &unreadable);
    if (unreadable)
      throw UnavailableError("job " + job_id +
                             ": its stored image cannot be read now (a file system error); retry");
    const bool succeeded = snap.status.state() == photonfarm::v1::JOB_STATE_SUCCEEDED;
    const auto lost = [&](const std::string& what) {
      return DataLossError(
          "job " + job_id + ": its stored image " + what + "; the results are lost" +
          (succeeded ? " (the coordinator renders the job again from zero when it restarts)" : ""));
    };
    if (!problem.empty()) throw lost(problem);
    if (cp && cp->job_id != job_id) throw lost("belongs to another job");
    try {
      const PlanSpec plan = PlanFromProto(snap.status.spec().plan(), "spec.plan");
      if (cp) stored = Accumulator::Deserialize(cp->accumulator, &plan);
    } catch (const std::exception& e) {
      throw lost(std::string("is damaged (") + e.what() + ")");
    }
    if (stored && stored->samples_merged() != snap.status.samples_merged())
      throw lost("holds " + std::to_string(stored->samples_merged()) + " samples, " +
                 std::to_string(snap.status.samples_merged()) + " expected");
    Accumulator acc =
        stored ? std::move(*stored)
               : Accumulator(PlanFromProto(snap.status.spec().plan(), "spec.plan"), snap.config->camera.width,
                             snap.config->image_height(), snap.config->settings.progressive_alpha);
    image = ResolveSnapshot(job_id, acc);
  }
  AddJobMetadata(snap.status, *snap.config, image.metadata);
  if (status) *status = std::move(snap.status);
  return image;
}

EncodedImage EncodeJobImage(Scheduler& scheduler, const std::string& job_id) {
  EncodedImage out;
  const ResolvedImage image = ResolveJobImage(scheduler, job_id, &out.status);
  const std::string exr = EncodeSnapshot(image);
  const std::vector<std::string_view> pieces = SplitChunks(exr);
  for (size_t i = 0; i < pieces.size(); ++i) {
    photonfarm::v1::ImageChunk chunk;
    chunk.set_index(uint32_t(i));
    chunk.set_count(uint32_t(pieces.size()));
    chunk.set_exr_bytes(std::string(pieces[i]));
    chunk.set_samples_merged(image.samples_merged);
    out.chunks.push_back(std::move(chunk));
  }
  return out;
}

}  // namespace pf::server
