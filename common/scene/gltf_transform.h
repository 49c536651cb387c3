#pragma once
// A glTF node's transform from its translation, rotation and scale, T·R·S (glTF 2.0 spec, §3.5.3):
// the still node's (gltf_loader.cpp) and an animated camera's at a key (gltf_camera_path.cpp).

#include <vector>

#include "common/scene/mgf_transform.h"

namespace pf {

// Each of size 3, 4 (x, y, z, w) and 3, or empty for none. The rotation is normalised; a zero or
// non-finite quaternion is no rotation.
mgf::Affine GltfTrs(const std::vector<double>& translation, const std::vector<double>& rotation,
                    const std::vector<double>& scale);

}  // namespace pf
