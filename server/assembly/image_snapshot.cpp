#include "server/assembly/image_snapshot.h"

#include <cstdio>

#include "common/image/exr_io.h"

namespace pf::server {
namespace {

std::string Format6(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

}  // namespace

ResolvedImage ResolveSnapshot(const std::string& job_id, const Accumulator& acc) {
  ResolvedImage out;
  out.image = acc.Resolve();
  out.samples_merged = acc.samples_merged();
  const double pixels = double(acc.width()) * acc.height();
  out.estimates = acc.Estimates();
  const double noise = out.estimates.noise;
  out.metadata["job_id"] = job_id;
  out.metadata["spp"] = Format6(pixels > 0 ? double(acc.samples_merged()) / pixels : 0.0);
  out.metadata["samples_merged"] = std::to_string(acc.samples_merged());
  out.metadata["tasks_merged"] = std::to_string(acc.tasks_merged());
  out.metadata["noise_rms"] = noise < 0 ? "unknown" : Format6(noise);
  // The progressive plan's bias indicator and the error it implies (common/plan/progressive_bias.h).
  if (acc.progressive_bias()) {
    out.metadata["bias_rms"] = out.estimates.bias < 0 ? "unknown" : Format6(out.estimates.bias);
    out.metadata["error_rms"] = out.estimates.error < 0 ? "unknown" : Format6(out.estimates.error);
  }
  return out;
}

std::string EncodeSnapshot(const ResolvedImage& snapshot) {
  return EncodeExrToMemory(snapshot.image, snapshot.metadata, ExrCompression::kZip);
}

std::vector<std::string_view> SplitChunks(std::string_view bytes, size_t max_bytes) {
  std::vector<std::string_view> chunks;
  if (max_bytes == 0) max_bytes = 1;
  for (size_t pos = 0; pos < bytes.size(); pos += max_bytes) chunks.push_back(bytes.substr(pos, max_bytes));
  if (chunks.empty()) chunks.push_back(bytes);
  return chunks;
}

}  // namespace pf::server
