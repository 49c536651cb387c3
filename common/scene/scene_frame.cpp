// The scene's frame (scene_frame.h).
#include "common/scene/scene_frame.h"

#include <cmath>

namespace pf {

Vec3d SceneFrameOrigin(const WorldBounds& bounds) {
  if (bounds.Empty()) return Vec3d();
  const Vec3d centre = (bounds.lo + bounds.hi) * 0.5;
  const Vec3d distance(std::fabs(centre.x), std::fabs(centre.y), std::fabs(centre.z));
  if (!(MaxComponent(distance) > MaxComponent(bounds.hi - bounds.lo))) return Vec3d();
  return centre;
}

void StoreInSceneFrame(const std::vector<Vec3d>& world, SceneDescription* scene) {
  WorldBounds bounds;
  for (const Vec3d& p : world) bounds.Extend(p);
  scene->origin = SceneFrameOrigin(bounds);
  scene->positions.resize(world.size());
  for (size_t i = 0; i < world.size(); ++i) scene->positions[i] = InSceneFrame(world[i], scene->origin);
}

void PlaceInSceneFrame(SceneDescription* scene) {
  WorldBounds bounds;
  for (const Vec3& p : scene->positions) bounds.Extend(Vec3d(p));
  const Vec3d origin = SceneFrameOrigin(bounds);
  if (origin == Vec3d()) return;
  scene->origin += origin;
  for (Vec3& p : scene->positions) p = InSceneFrame(Vec3d(p), origin);
}

}  // namespace pf
