#pragma once
// A glTF camera's animation as a camera path (camera_path.h; docs/gltf.md "Camera animation"): the
// channels of the first animation that moves the scene's camera node — its translation and rotation
// (spec §3.11) — sampled at every frame f from the first key's to the last key's, at time
// (f − 1) / 24, so key time t is frame 1 + round(24 · t): Blender exports
// frame f of a 24 fps scene that starts at frame 1 at t = (f − 1) / 24, so the frames keep their
// numbers. At each key the camera is the node's world transform, as a still glTF camera is
// (gltf_loader.h): eye at its origin, looking down its −Z (look-at 1 m ahead) with its +Y up.
// LINEAR rotations are slerped and translations lerped between keys, STEP holds a key's value,
// CUBICSPLINE keys take their value (not the tangents). At most kMaxGltfPathFrames frames.
// Only the camera node's own transform moves: its parents are taken at rest, and an animated scale
// is ignored (warned). The scene itself stays at rest (rendered frames share one set of maps).

#include <string>
#include <vector>

#include "common/scene/gltf_document.h"
#include "common/scene/mgf_transform.h"
#include "common/scene/scene.h"

namespace pf {

inline constexpr double kGltfFramesPerSecond = 24.0;
// A path has a key per frame (below): keys after this frame are not used (warned).
inline constexpr long kMaxGltfPathFrames = 10000;

// The path of camera node `node` whose parent's world transform is `parent`; no keys if no animation
// moves it. InputError naming the animation (file: animations[i].channels[j]: …) for a malformed one
// (the loader makes it a warning: the scene still loads, without a path).
CameraPath GltfCameraPath(const GltfDocument& doc, int node, const mgf::Affine& parent,
                          std::vector<std::string>* warnings);

}  // namespace pf
