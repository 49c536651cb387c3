#pragma once
// glTF 2.0 scenes (.gltf + .bin, .glb) → SceneDescription (docs/gltf.md).
//
// What is read: the nodes of the default scene (or scene 0; with no scenes, every root node),
// depth first, each with its TRS or matrix transform composed onto its parent's (glTF 2.0
// spec, §3.5.3: M = T·R·S); positions are transformed in double, the scene's frame
// (scene_frame.h) chosen from their bounds, and then rounded once to float. Normals are
// transformed by the inverse transpose; a mirroring transform (negative determinant) reverses
// the winding so that the front face stays the spec's counter-clockwise one. Mesh primitives
// of mode TRIANGLES with POSITION, optional NORMAL and indices of any width (or none); other
// modes are skipped with a warning naming `meshes[m].primitives[p]`. Every primitive instance
// whose material emits is one light (scene.h). The first perspective camera in node order is
// the scene's camera (gltf_loader.cpp, CameraOfNode); KHR_lights_punctual lights go through
// gltf_lights.h, materials through gltf_materials.h.
//
// Errors are InputErrors naming the file and the element ("scene.gltf: meshes[3].primitives[0]:
// index 9 is out of range (6 vertices)"). A node hierarchy that is not a forest (a node with two
// parents, or a cycle) is refused; SceneBudget bounds triangles and vertices.

#include <filesystem>

#include "common/scene/scene.h"
#include "common/scene/scene_budget.h"

namespace pf {

class PixelAllowance;  // common/image/image_file.h

// `root`: the folder external buffers must stay in (empty: the folder of `path`).
// `texels`: the load's image allowance, shared with its other images (null: budget.max_texels
// for this file's).
SceneDescription LoadGltf(const std::filesystem::path& path, const std::filesystem::path& root = {},
                          const SceneBudget& budget = {}, PixelAllowance* texels = nullptr);

}  // namespace pf
