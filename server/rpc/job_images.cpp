#include "server/rpc/job_images.h"

#include "common/core/error.h"
#include "server/assembly/image_snapshot.h"
#include "server/errors.h"
#include "server/store/checkpoint.h"

namespace pf::server {

EncodedImage EncodeJobImage(Scheduler& scheduler, const std::string& job_id) {
  JobSnapshot snap = scheduler.Snapshot(job_id, /*with_image=*/true);
  ResolvedImage image;
  if (snap.image) {
    image = std::move(*snap.image);
  } else {
    // A finished job's image lives only in its checkpoint: a damaged, foreign or missing one
    // means acknowledged results are lost (DATA_LOSS, no server path in the message).
    std::optional<Checkpoint> cp;
    std::optional<Accumulator> stored;
    try {
      cp = ReadCheckpointFile(snap.checkpoint_path);
      if (cp && cp->job_id != job_id)
        throw DataLossError("job " + job_id + ": its stored image belongs to another job");
      if (cp) stored = Accumulator::Deserialize(cp->accumulator);
    } catch (const DataLossError&) {
      throw;
    } catch (const std::exception& e) {
      std::string reason = e.what();
      if (const size_t colon = reason.rfind("checkpoint:"); colon != std::string::npos) reason = reason.substr(colon);
      throw DataLossError("job " + job_id + ": its stored image is damaged (" + reason + "); the results are lost");
    }
    if (!cp && snap.status.tasks_done() > 0)
      throw DataLossError("job " + job_id + ": its stored image is missing; the results are lost");
    Accumulator acc = stored ? std::move(*stored)
                             : Accumulator(int(snap.status.spec().camera().width()),
                                           int(snap.status.spec().camera().height()));
    image = ResolveSnapshot(job_id, acc);
  }
  const std::string exr = EncodeSnapshot(image);
  EncodedImage out;
  out.status = std::move(snap.status);
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
