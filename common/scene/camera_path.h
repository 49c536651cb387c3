#pragma once
// A camera path: keyframes of a camera's eye, look-at point, up vector and field of view, by frame
// number (docs/scene-manifest.md "camera_path"; docs/farm.md "Animation"). A frame between two keys
// takes each value by linear interpolation between them — as glTF's LINEAR animation sampler does —
// so the path is continuous and passes through every key exactly. Only the camera moves: the scene
// is static, which is what lets every frame share one set of photon maps (the map key holds no
// camera).

#include <vector>

#include "common/scene/scene.h"

namespace pf {

// The camera of `frame` (within [first_frame, last_frame]): `base` (name, resolution, and the up and
// field of view a key leaves out) with the interpolated eye, look-at, up and field of view, named
// "<base name>@<frame>". Throws InputError when the frame is outside the path or the interpolated
// view is degenerate (eye on its look-at point, up parallel to the view).
CameraSpec CameraAtFrame(const CameraPath& path, const CameraSpec& base, int frame);

// The frames of the path (first..last) as cameras, checked (CameraAtFrame).
std::vector<CameraSpec> CamerasOfFrames(const CameraPath& path, const CameraSpec& base, int first, int last);

}  // namespace pf
