#include "client/frame_files.h"

#include <fmt/format.h>

#include <cctype>

#include "common/core/atomic_file.h"
#include "common/core/error.h"
#include "common/image/exr_io.h"
#include "common/plan/render_header.h"
#include "proto/convert.h"

namespace pf {
namespace v1 = photonfarm::v1;

bool IsAnimation(const v1::JobSpec& spec) {
  return spec.has_animation() && spec.animation().cameras_size() > 0;
}

std::string FramePattern(const std::string& output, const char* flag) {
  const size_t percent = output.find('%');
  if (percent == std::string::npos) {
    const size_t dot = output.rfind('.');
    const size_t slash = output.rfind('/');
    const size_t at =
        dot == std::string::npos || (slash != std::string::npos && dot < slash) ? output.size() : dot;
    return output.substr(0, at) + ".%04d" + output.substr(at);
  }
  size_t i = percent + 1;
  if (i < output.size() && output[i] == '0') {
    ++i;
    if (i < output.size() && std::isdigit(static_cast<unsigned char>(output[i]))) ++i;
  }
  if (i >= output.size() || output[i] != 'd' || output.find('%', i) != std::string::npos)
    throw InputError(
        std::string(flag) + ": '" + output +
        "': an animation's output names its frames with one %d or %0Nd (N ≤ 9), e.g. out.%04d.exr");
  return output;
}

std::string FramePath(const std::string& pattern, uint32_t frame) {
  const size_t percent = pattern.find('%');
  const size_t d = pattern.find('d', percent);
  const std::string flags = pattern.substr(percent + 1, d - percent - 1);  // "", "0" or "0N"
  const int width = flags.size() == 2 ? flags[1] - '0' : 0;
  return pattern.substr(0, percent) + fmt::format("{:0{}}", frame, width) + pattern.substr(d + 1);
}

std::vector<std::string> WriteFrameFiles(const std::string& pattern, const std::string& exr_bytes,
                                         const v1::JobSpec& spec, const ImageMetadata& extra) {
  ImageMetadata meta;
  const Image stacked = DecodeExrFromMemory(exr_bytes, &meta);
  const int frames = spec.animation().cameras_size();
  const int height = int(spec.camera().height());
  if (frames <= 0 || height <= 0 || stacked.height() != height * frames)
    throw InputError("the job's image is " + std::to_string(stacked.width()) + "x" +
                     std::to_string(stacked.height()) + ", not " + std::to_string(frames) +
                     " frames of height " + std::to_string(height));
  for (const auto& [key, value] : extra) meta[key] = value;
  std::vector<std::string> paths;
  for (int f = 0; f < frames; ++f) {
    Image frame(stacked.width(), height);
    std::copy(stacked.pixels().begin() + ptrdiff_t(size_t(f) * height * stacked.width()),
              stacked.pixels().begin() + ptrdiff_t(size_t(f + 1) * height * stacked.width()),
              frame.pixels().begin());
    ImageMetadata m = meta;
    const uint32_t number = spec.animation().first_frame() + uint32_t(f);
    RecordCamera(
        CameraFromProto(spec.animation().cameras(f), "spec.animation.cameras[" + std::to_string(f) + "]"), m);
    m["frame"] = std::to_string(number);
    paths.push_back(FramePath(pattern, number));
    WriteFileAtomically(paths.back(), EncodeExrToMemory(frame, m));
  }
  return paths;
}

std::string WriteJobImage(const std::string& output, const std::string& exr_bytes, const v1::JobSpec& spec) {
  if (!IsAnimation(spec)) {
    WriteFileAtomically(output, exr_bytes);
    return output;
  }
  const std::vector<std::string> paths = WriteFrameFiles(FramePattern(output, "-o"), exr_bytes, spec);
  return paths.front() + " .. " + paths.back() + " (" + std::to_string(paths.size()) + " frames)";
}

}  // namespace pf
