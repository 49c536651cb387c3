#pragma once
// An animation's image on disk (docs/farm.md "Animation"): the coordinator keeps a job's frames as
// one image, stacked top to bottom (common/plan/frame_tasks.h); pf writes each frame to a file of its
// own, named by a printf pattern (out.%04d.exr), with its header's camera.* keys the frame's camera
// and `frame` its number (the other keys, the job's, are the same in every frame).

#include <string>
#include <vector>

#include "common/image/image.h"
#include "photonfarm/v1/farm.pb.h"

namespace pf {

bool IsAnimation(const photonfarm::v1::JobSpec& spec);

// The output pattern for `output`: kept when it holds one %d or %0Nd (N ≤ 9) and no other '%';
// without any '%', ".%04d" goes before the extension (out.exr → out.%04d.exr). InputError (naming
// `flag`) for any other use of '%'.
std::string FramePattern(const std::string& output, const char* flag);
// The pattern with the frame number in it.
std::string FramePath(const std::string& pattern, uint32_t frame);

// Writes the frames of an animation job's image (its EXR bytes as GetImage returns them), each
// atomically, with `extra` added to every header; returns the paths written, in frame order.
// InputError if the image's height is not the spec's frames × height.
std::vector<std::string> WriteFrameFiles(const std::string& pattern, const std::string& exr_bytes,
                                         const photonfarm::v1::JobSpec& spec,
                                         const ImageMetadata& extra = {});

// A job's image to `output`: the EXR as it is for a still image; an animation's frames to
// FramePattern(output) (WriteFrameFiles). Returns what was written, for a message: the path, or
// "first .. last (N frames)".
std::string WriteJobImage(const std::string& output, const std::string& exr_bytes,
                          const photonfarm::v1::JobSpec& spec);

}  // namespace pf
