#pragma once
// The merged image of a job as EXR chunks, for GetImage and WatchJob snapshots: from the live
// accumulator, or — for a finished job reloaded after a restart — from its checkpoint file.

#include <string>
#include <vector>

#include "photonfarm/v1/farm.pb.h"
#include "server/scheduling/scheduler.h"

namespace pf::server {

struct EncodedImage {
  photonfarm::v1::JobStatus status;  // taken at the same moment as the pixels
  std::vector<photonfarm::v1::ImageChunk> chunks;
};

// The job's merged image and its header (what the image is of), with the status of the same
// moment. O(pixels); NotFoundError for an unknown job. The web page's PNG previews use it.
ResolvedImage ResolveJobImage(Scheduler& scheduler, const std::string& job_id,
                              photonfarm::v1::JobStatus* status);

// Slow (EXR encoding): call on the Executor. NotFoundError for an unknown job.
EncodedImage EncodeJobImage(Scheduler& scheduler, const std::string& job_id);

}  // namespace pf::server
