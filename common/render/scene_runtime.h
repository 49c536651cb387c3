#pragma once
// A scene ready to trace, built once per scene per process (ExecuteTask: pf-worker, `pf render`).

#include "common/accel/embree_scene.h"
#include "common/lights/light_sampler.h"
#include "common/scene/scene.h"

namespace pf {

// A scene ready to trace: description + Embree + lights. Built once per scene per process.
//
// Traced in the description's frame (scene_frame.h): a scene far from the world origin was
// stored by its loader relative to its centre, so hit points, photon positions and kd-tree boxes
// have the precision of the scene's size. Cameras are world coordinates; ExecuteTask builds its
// Camera with description.origin, and code that traces `accel` itself must do the same.
struct SceneRuntime {
  explicit SceneRuntime(SceneDescription description);
  SceneDescription description;
  EmbreeScene accel;
  LightSampler lights;
};

}  // namespace pf
