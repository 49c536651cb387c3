#pragma once
// Pinhole camera with a vertical field of view; image right = forward × up.
// Pixel filter: a one-pixel box — a sample (u, v) ∈ [0,1)² lands uniformly in the pixel.

#include <cmath>

#include "common/accel/ray.h"
#include "common/core/error.h"
#include "common/scene/scene.h"
#include "common/scene/scene_frame.h"

namespace pf {

class Camera {
 public:
  // `spec` in world coordinates; rays start in the scene's frame, the one whose world position
  // is `frame_origin` (SceneDescription::origin, scene_frame.h): eye and look-at are moved there
  // in double and rounded once. A scene around the origin has frame_origin 0.
  explicit Camera(const CameraSpec& spec, const Vec3d& frame_origin = Vec3d())
      : spec_(spec), eye_(InSceneFrame(spec.eye, frame_origin)) {
    if (spec.width <= 0 || spec.height <= 0)
      throw InputError("camera '" + spec.name + "': resolution must be positive");
    if (!(spec.vfov_degrees > 0.0f && spec.vfov_degrees < 180.0f))
      throw InputError("camera '" + spec.name + "': fov must be in (0, 180) degrees");
    const Vec3 f = InSceneFrame(spec.look_at, frame_origin) - eye_;
    if (!(LengthSquared(f) > 0.0f) || !IsFinite(f) || !IsFinite(eye_))
      throw InputError("camera '" + spec.name + "': eye and look-at must differ");
    forward_ = Normalize(f);
    const Vec3 r = Cross(forward_, spec.up);
    if (!(LengthSquared(r) > 1e-12f))
      throw InputError("camera '" + spec.name + "': up must not be parallel to the view direction");
    right_ = Normalize(r);
    up_ = Cross(right_, forward_);
    tan_half_ = std::tan(0.5f * spec.vfov_degrees * kPi / 180.0f);
    aspect_ = float(spec.width) / float(spec.height);
  }

  // Primary ray through image position (px + u, py + v), (0,0) = top-left corner.
  Ray GenerateRay(int px, int py, float u, float v) const {
    const float sx = (2.0f * (float(px) + u) / float(spec_.width) - 1.0f) * tan_half_ * aspect_;
    const float sy = (1.0f - 2.0f * (float(py) + v) / float(spec_.height)) * tan_half_;
    return Ray{eye_, Normalize(forward_ + right_ * sx + up_ * sy)};
  }

  // The eye in the scene's frame, as rays start from it.
  const Vec3& eye() const { return eye_; }
  const CameraSpec& spec() const { return spec_; }
  int width() const { return spec_.width; }
  int height() const { return spec_.height; }

 private:
  CameraSpec spec_;
  Vec3 eye_;
  Vec3 forward_, right_, up_;
  float tan_half_ = 1.0f, aspect_ = 1.0f;
};

}  // namespace pf
