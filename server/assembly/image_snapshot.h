#pragma once
// The merged image as clients receive it (GetImage, WatchJob snapshots): the Accumulator
// resolved (Σ w·c / Σ w per pixel) and encoded as EXR (float32 RGB, linear, ZIP), split into
// chunks of at most kImageChunkBytes so that images larger than gRPC's default 4 MiB message
// limit stream.
//
// The EXR carries metadata "pf:job_id", "pf:spp" (merged samples / pixels), "pf:samples_merged",
// "pf:tasks_merged" and "pf:noise_rms" (6 significant digits; "unknown" until two maps cover a
// pixel). All of them are functions of the accumulator's content, so two snapshots of the same
// merged state are byte-identical (the last WatchJob snapshot equals GetImage).

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "common/image/image.h"
#include "common/plan/accumulator.h"

namespace pf::server {

inline constexpr size_t kImageChunkBytes = size_t(1) << 20;

// The pixels and metadata of a snapshot, taken under the scheduler's lock (cheap: O(pixels)).
struct ResolvedImage {
  Image image;
  ImageMetadata metadata;
  uint64_t samples_merged = 0;
  ErrorEstimates estimates;  // Accumulator::Estimates at that moment
};
ResolvedImage ResolveSnapshot(const std::string& job_id, const Accumulator& acc);

// The EXR bytes (slow part: run outside any lock).
std::string EncodeSnapshot(const ResolvedImage& snapshot);

// Consecutive pieces of at most `max_bytes` (at least one piece, possibly empty).
std::vector<std::string_view> SplitChunks(std::string_view bytes, size_t max_bytes = kImageChunkBytes);

}  // namespace pf::server
