#include "common/scene/camera_path.h"

#include <algorithm>

#include "common/core/error.h"

namespace pf {
namespace {

template <typename T>
T Lerp(const T& a, const T& b, double t) {
  return a + (b - a) * t;
}

}  // namespace

CameraSpec CameraAtFrame(const CameraPath& path, const CameraSpec& base, int frame) {
  if (path.keys.empty()) throw InputError("camera path: it has no keys");
  if (frame < path.first_frame() || frame > path.last_frame())
    throw InputError("frame " + std::to_string(frame) + ": outside the camera path's frames " +
                     std::to_string(path.first_frame()) + "-" + std::to_string(path.last_frame()));
  // The last key at or before the frame, and the one after it (if any).
  const auto after = std::upper_bound(path.keys.begin(), path.keys.end(), frame,
                                      [](int f, const CameraKey& k) { return f < k.frame; });
  const CameraKey& a = *(after - 1);
  const CameraKey& b = after == path.keys.end() ? a : *after;
  const double t = b.frame == a.frame ? 0.0 : double(frame - a.frame) / double(b.frame - a.frame);
  const Vec3 up_a = a.up.value_or(base.up), up_b = b.up.value_or(base.up);
  const float fov_a = a.vfov_degrees.value_or(base.vfov_degrees),
              fov_b = b.vfov_degrees.value_or(base.vfov_degrees);
  CameraSpec c = base;
  c.name = base.name + "@" + std::to_string(frame);
  // A key's frame takes the key's values exactly (t = 0), not a rounding of them.
  c.eye = t == 0.0 ? a.eye : Lerp(a.eye, b.eye, t);
  c.look_at = t == 0.0 ? a.look_at : Lerp(a.look_at, b.look_at, t);
  c.up = t == 0.0 ? up_a : Lerp(up_a, up_b, float(t));
  c.vfov_degrees = t == 0.0 ? fov_a : fov_a + (fov_b - fov_a) * float(t);
  const std::string where = "camera path, frame " + std::to_string(frame) + ": ";
  if (!(LengthSquared(Vec3(c.look_at - c.eye)) > 0.0f))
    throw InputError(where + "the eye is on its look-at point");
  if (!(LengthSquared(Cross(Normalize(Vec3(c.look_at - c.eye)), c.up)) > 1e-12f))
    throw InputError(where + "up is parallel to the view direction");
  return c;
}

std::vector<CameraSpec> CamerasOfFrames(const CameraPath& path, const CameraSpec& base, int first, int last) {
  std::vector<CameraSpec> cameras;
  for (int f = first; f <= last; ++f) cameras.push_back(CameraAtFrame(path, base, f));
  return cameras;
}

}  // namespace pf
