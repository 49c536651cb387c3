#pragma once
// A scene ready to trace (implemented in task_executor.cpp).

#include "common/accel/embree_scene.h"
#include "common/render/light_sampler.h"
#include "common/scene/scene.h"

namespace pf {

// A scene ready to trace: description + Embree + lights. Built once per scene per process.
struct SceneRuntime {
  explicit SceneRuntime(SceneDescription description);
  SceneDescription description;
  EmbreeScene accel;
  LightSampler lights;
};

}  // namespace pf
