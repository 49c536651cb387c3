#include "common/render/light_reach.h"

#include <tbb/parallel_for.h>

#include <atomic>
#include <cmath>

#include "common/materials/bsdf.h"
#include "common/render/pilot_lattice.h"
#include "common/sampling/hashed_uniform.h"

namespace pf {
namespace {

// Whether light sample `ls` reaches x on the side `n` faces (the side the camera sees); a zero n is
// a point in open space, which light reaches from every side.
bool Reaches(const SceneRuntime& scene, const LightSample& ls, const Vec3& x, const Vec3& n) {
  const bool surface = Dot(n, n) > 0.0f;
  if (ls.environment)
    return (!surface || Dot(n, ls.wi) > 0.0f) && scene.lights.UnoccludedTowards(x, n, ls.wi);
  if (ls.delta()) {
    const DeltaIncidence in = scene.lights.Incidence(ls, x);
    return !in.irradiance.IsBlack() && (!surface || Dot(n, in.wi) > 0.0f) &&
           scene.lights.Unoccluded(x, n, in);
  }
  const Vec3 to_light = ls.position - x;
  if ((surface && Dot(n, to_light) <= 0.0f) || Dot(ls.normal, to_light) >= 0.0f) return false;  // behind
  return scene.accel.Visible(x, n, ls.position, ls.normal);
}

// Whether a photon search of radius `reach` around the hit x (seen on side n) would reach, through
// a wall, space that some light reaches: rays from x over its visible hemisphere (8 azimuths at two
// elevations) that meet a surface within `reach` are followed through it to the point just beyond,
// and, if they meet another surface within reach, to the point just beyond that too (the far face
// of a wall with thickness); either point lit is a leak. The point just beyond the face of a thick
// wall lies inside it, where no light reaches. A sphere search does not stop at walls: photons
// stored there would be found from x (light bleeding, Wald 1999, §3.3.4).
template <typename LitAt>
bool BehindThinWall(const SceneRuntime& scene, const SurfaceHit& x, const Vec3& n, float reach,
                    const LitAt& lit_at) {
  const Frame frame(n);
  const float step = std::max(1e-3f * reach, 4.0f * scene.accel.epsilon());
  const Vec3 open_space(0.0f);
  uint64_t salt = 1u << 20;
  for (const float sin_elevation : {0.2f, 0.6f}) {
    const float cos_elevation = std::sqrt(1.0f - sin_elevation * sin_elevation);
    for (int a = 0; a < 8; ++a, salt += 1u << 10) {
      const float phi = float(a) * 0.25f * 3.14159265f;
      const Vec3 dir =
          frame.ToWorld({std::cos(phi) * cos_elevation, std::sin(phi) * cos_elevation, sin_elevation});
      const std::optional<SurfaceHit> wall =
          scene.accel.Intersect(Ray{scene.accel.SpawnOrigin(x, dir), dir, reach});
      if (!wall) continue;
      const float left = reach - wall->t;
      if (left <= step) continue;
      if (lit_at(wall->position + dir * step, open_space, salt)) return true;
      const std::optional<SurfaceHit> far_face =
          scene.accel.Intersect(Ray{scene.accel.SpawnOrigin(*wall, dir), dir, left});
      if (far_face && left - far_face->t > step &&
          lit_at(far_face->position + dir * step, open_space, salt + (1u << 9)))
        return true;
    }
  }
  return false;
}

}  // namespace

LightReach MeasureLightReach(const SceneRuntime& scene, const Camera& camera, float leak_distance, int grid,
                             int shadow_rays) {
  const SceneDescription& desc = scene.description;
  std::atomic<int> points{0}, lit{0}, leaks{0};
  tbb::parallel_for(0, grid, [&](int j) {
    int row_points = 0, row_lit = 0, row_leaks = 0;
    for (int i = 0; i < grid; ++i) {
      const Ray ray = PilotLatticeRay(camera, grid, i, j);
      const std::optional<SurfaceHit> hit = scene.accel.Intersect(ray);
      if (!hit) continue;
      const Material& m = desc.materials[hit->material];
      if (m.IsEmissive() && hit->front_face) continue;
      const Bsdf bsdf(m, hit->shading_normal, hit->geometric_normal);
      if (!bsdf.HasNonDelta()) continue;
      ++row_points;
      const Vec3 n =
          Dot(hit->geometric_normal, ray.direction) < 0.0f ? hit->geometric_normal : -hit->geometric_normal;
      const uint64_t cell = uint64_t(j) * uint64_t(grid) + uint64_t(i);
      // Whether some light sample reaches x on the side `side` faces; `salt` draws other numbers.
      const auto lit_at = [&](const Vec3& x, const Vec3& side, uint64_t salt) {
        for (int s = 0; s < shadow_rays; ++s) {
          const uint64_t k = uint64_t(s) + salt;
          const LightSample ls = scene.lights.Sample(HashedUniform(cell, k, 0), HashedUniform(cell, k, 1),
                                                     HashedUniform(cell, k, 2));
          if (ls.pdf_area > 0.0f && Reaches(scene, ls, x, side)) return true;
        }
        return false;
      };
      if (lit_at(hit->position, n, 0)) {
        ++row_lit;
        continue;
      }
      if (leak_distance > 0.0f && BehindThinWall(scene, *hit, n, leak_distance, lit_at)) ++row_leaks;
    }
    points += row_points;
    lit += row_lit;
    leaks += row_leaks;
  });
  LightReach r;
  r.points = points.load();
  r.lit_fraction = r.points > 0 ? double(lit.load()) / double(r.points) : 0.0;
  r.leak_fraction = r.points > 0 ? double(leaks.load()) / double(r.points) : 0.0;
  return r;
}

}  // namespace pf
