#pragma once
// A scene ready to trace (implemented in task_executor.cpp).

#include "common/accel/embree_scene.h"
#include "common/render/light_sampler.h"
#include "common/scene/scene.h"

namespace pf {

// A scene ready to trace: description + Embree + lights. Built once per scene per process.
//
// A scene far from the world origin (its centre farther than its size, e.g. a georeferenced
// model at 1e6 m) is traced in a local frame: `description.positions` are moved by −origin
// (exact in float for such scenes: p and the centre are within a factor of 2), so hit points,
// photon positions and kd-tree boxes keep the precision of the scene's size instead of the
// coordinates' magnitude (at 1e6 floats are 6.25 cm apart, and a photon map there collapses
// its photons onto that lattice: docs/results/hard_cases.md). Cameras stay in world
// coordinates (those in `description.cameras` too); ExecuteTask moves the one it renders
// with, and code that traces `accel` itself must move its camera by −origin likewise. For
// every other scene origin is 0 and nothing moves.
struct SceneRuntime {
  explicit SceneRuntime(SceneDescription description);
  Vec3 origin;  // world position of the local frame's origin (0 unless the scene is far away)
  SceneDescription description;
  EmbreeScene accel;
  LightSampler lights;
};

}  // namespace pf
