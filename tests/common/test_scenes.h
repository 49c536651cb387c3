#pragma once
// Small programmatic scenes for analytic tests (no loader involved, so a loader bug cannot
// mask or fake a renderer result).

#include <array>
#include <cmath>
#include <map>
#include <utility>

#include "common/scene/scene.h"

namespace pf::testing {

// A programmatic scene with the camera its test renders it with.
struct SceneWithCamera {
  SceneDescription scene;
  CameraSpec camera;
};

inline uint32_t AddMaterial(SceneDescription& s, Material m) {
  s.materials.push_back(std::move(m));
  return uint32_t(s.materials.size() - 1);
}

inline void AddTriangle(SceneDescription& s, uint32_t a, uint32_t b, uint32_t c, uint32_t material,
                        uint32_t light = kNoLight) {
  s.triangles.push_back({a, b, c});
  s.triangle_material.push_back(material);
  s.triangle_light.push_back(light);
}

// Quad p0,p1,p2,p3 in counter-clockwise order seen from the front (normal side).
inline void AddQuad(SceneDescription& s, Vec3 p0, Vec3 p1, Vec3 p2, Vec3 p3, uint32_t material,
                    uint32_t light = kNoLight) {
  const uint32_t base = uint32_t(s.positions.size());
  for (const Vec3& p : {p0, p1, p2, p3}) {
    s.positions.push_back(p);
    if (!s.normals.empty()) s.normals.push_back(Vec3(0.0f));
  }
  AddTriangle(s, base, base + 1, base + 2, material, light);
  AddTriangle(s, base, base + 2, base + 3, material, light);
}

// A 10 m grey floor (ρ = 0.5, material 0) in the plane z = 0 under a square light of radiance 20
// (material 1, light 0) with corners (±half, ±half) 1 m above it, facing down: the analytic
// floor-under-a-small-light scene of the path tracer and renderer tests, seen by FloorCamera.
inline SceneDescription FloorUnderSquareLight(float half) {
  SceneDescription scene;
  const uint32_t floor_id = AddMaterial(scene, Material{.name = "floor", .diffuse_reflectance = Rgb(0.5f)});
  const uint32_t light_id = AddMaterial(scene, Material{.name = "light", .emission = Rgb(20.0f)});
  AddQuad(scene, {-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}, floor_id);
  // Vertices clockwise seen from above: the front faces down (-z).
  AddQuad(scene, {-half, -half, 1}, {-half, half, 1}, {half, half, 1}, {half, -half, 1}, light_id, 0);
  scene.num_lights = 1;
  return scene;
}

// Geodesic sphere from a subdivided octahedron. `inward` flips the winding so that the front
// faces (and shading normals) point to the centre. `smooth` adds vertex normals; without them
// the sphere is a closed polyhedron with flat facets (exact for furnace tests: shading normals
// make a Lambertian surface lose or gain energy at grazing angles).
inline void AddSphere(SceneDescription& s, Vec3 center, float radius, int subdivisions, uint32_t material,
                      bool inward, uint32_t light = kNoLight, bool smooth = true) {
  std::vector<Vec3> verts = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  std::vector<std::array<uint32_t, 3>> faces = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                                                {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoint;
    auto mid = [&](uint32_t a, uint32_t b) {
      auto key = std::minmax(a, b);
      auto it = midpoint.find(key);
      if (it != midpoint.end()) return it->second;
      verts.push_back(Normalize(verts[a] + verts[b]));
      return midpoint[key] = uint32_t(verts.size() - 1);
    };
    std::vector<std::array<uint32_t, 3>> next;
    for (const auto& f : faces) {
      const uint32_t ab = mid(f[0], f[1]), bc = mid(f[1], f[2]), ca = mid(f[2], f[0]);
      next.push_back({f[0], ab, ca});
      next.push_back({ab, f[1], bc});
      next.push_back({ca, bc, f[2]});
      next.push_back({ab, bc, ca});
    }
    faces = std::move(next);
  }
  const uint32_t base = uint32_t(s.positions.size());
  if (smooth && s.normals.size() < s.positions.size()) s.normals.resize(s.positions.size(), Vec3(0.0f));
  for (const Vec3& v : verts) {
    s.positions.push_back(center + v * radius);
    if (smooth) {
      s.normals.push_back(inward ? -v : v);
    } else if (!s.normals.empty()) {
      s.normals.push_back(Vec3(0.0f));
    }
  }
  for (const auto& f : faces) {
    if (inward)
      AddTriangle(s, base + f[0], base + f[2], base + f[1], material, light);
    else
      AddTriangle(s, base + f[0], base + f[1], base + f[2], material, light);
  }
}

// A furnace (Wald 1999, §4.3 tests): a closed inward sphere of radius 1 at the origin, Lambertian
// albedo `albedo` and emission 1 everywhere (flat facets: see AddSphere), so the radiance is
// Le / (1 - albedo) at every point and in every direction.
inline SceneDescription FurnaceScene(float albedo) {
  SceneDescription s;
  Material wall;
  wall.diffuse_reflectance = Rgb(albedo);
  wall.emission = Rgb(1.0f);
  AddSphere(s, Vec3(0.0f), 1.0f, 5, AddMaterial(s, wall), /*inward=*/true, 0, /*smooth=*/false);
  s.num_lights = 1;
  return s;
}

// A 4x4 camera with a 90° field of view at the furnace's centre, looking down -z.
inline CameraSpec FurnaceCamera() {
  CameraSpec cam;
  cam.eye = Vec3(0.0f);
  cam.look_at = Vec3(0, 0, -1);
  cam.width = cam.height = 4;
  cam.vfov_degrees = 90;
  return cam;
}

// A camera at `eye` looking at `look_at` with `up` upwards, its vertical field of view and size.
inline CameraSpec LookAtCamera(Vec3 eye, Vec3 look_at, Vec3 up, float vfov_degrees, int width, int height) {
  return CameraSpec{.eye = eye,
                    .look_at = look_at,
                    .up = up,
                    .vfov_degrees = vfov_degrees,
                    .width = width,
                    .height = height};
}

// The camera the FloorUnderSquareLight tests render with: 32x32, 1.5 m up, looking down the floor.
inline CameraSpec FloorCamera() {
  return LookAtCamera(Vec3(2.5f, 0.0f, 1.5f), Vec3(0.5f, 0.0f, 0.0f), Vec3(0, 0, 1), 50.0f, 32, 32);
}

inline void ScaleScene(SceneDescription& s, CameraSpec& camera, float scale) {
  for (Vec3& p : s.positions) p *= scale;
  camera.eye *= scale;
  camera.look_at *= scale;
}

}  // namespace pf::testing
