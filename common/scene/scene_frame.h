#pragma once
// The frame a scene's positions are stored in (SceneDescription::origin).
//
// World coordinates are doubles until they are stored; the renderer traces floats, and floats
// 1e6 from the origin are 6.25 cm apart. Rounded to world floats there, a model loses its shape
// (the shipped Cornell box translated by 1e6: its light and its ceiling, 1 cm apart, round onto
// one plane) and a photon map piles its photons onto that lattice (docs/results/hard_cases.md,
// "Far from the origin"). So a scene whose centre is farther from the world origin than the
// scene is large is stored relative to the centre of its bounds, subtracted in double before
// anything is rounded: its floats have the precision of its size, not of its distance. Every
// other scene keeps origin 0: its floats, and its images, are those of world coordinates.
//
// One rule, applied once, where a description is made: the loaders (MGF, OBJ) apply it to their
// double-precision world points before storing floats; descriptions built in code go through
// PlaceInSceneFrame. Cameras stay in world coordinates (CameraSpec, double); Camera
// (camera/camera.h) moves them into the frame with the scene's origin.

#include <limits>
#include <vector>

#include "common/core/math.h"
#include "common/scene/scene.h"

namespace pf {

// Bounds of world points, in double.
struct WorldBounds {
  Vec3d lo{std::numeric_limits<double>::infinity()};
  Vec3d hi{-std::numeric_limits<double>::infinity()};
  void Extend(const Vec3d& p) {
    lo = Min(lo, p);
    hi = Max(hi, p);
  }
  bool Empty() const { return lo.x > hi.x || lo.y > hi.y || lo.z > hi.z; }
};

// The rule: the centre of `bounds` if its largest coordinate magnitude exceeds the bounds'
// largest extent, else 0 (also for empty bounds).
Vec3d SceneFrameOrigin(const WorldBounds& bounds);

// A world point in the frame of `origin`, rounded once to float.
inline Vec3 InSceneFrame(const Vec3d& world, const Vec3d& origin) {
  return Vec3(world - origin);
}

// Chooses the frame of the world points `world` (SceneFrameOrigin of their bounds), sets
// scene->origin and replaces scene->positions by the points in that frame.
void StoreInSceneFrame(const std::vector<Vec3d>& world, SceneDescription* scene);

// For a description built in code whose float positions are world coordinates (origin 0):
// chooses its frame by the same rule and moves the positions into it (p − origin in double,
// rounded once). A scene around the origin is left as it is.
void PlaceInSceneFrame(SceneDescription* scene);

}  // namespace pf
