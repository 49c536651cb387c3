#include "server/rpc/job_images.h"

#include "common/core/error.h"
#include "server/assembly/image_snapshot.h"
#include "server/store/checkpoint.h"

namespace pf::server {

EncodedImage EncodeJobImage(Scheduler& scheduler, const std::string& job_id) {
  JobSnapshot snap = scheduler.Snapshot(job_id, /*with_image=*/true);
  ResolvedImage image;
  if (snap.image) {
    image = std::move(*snap.image);
  } else {
    std::optional<Checkpoint> cp = ReadCheckpointFile(snap.checkpoint_path);
    Accumulator acc = cp ? Accumulator::Deserialize(cp->accumulator)
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
