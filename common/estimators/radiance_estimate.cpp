#include "common/estimators/radiance_estimate.h"

#include <cmath>
#include <limits>

namespace pf {

int AdaptiveK(const Vec3& x, std::span<const Vec3> nearest_sorted, int k_min) {
  const int k = int(nearest_sorted.size());
  if (k_min <= 0 || k <= k_min || k < 2) return k;
  Vec3 cog(0.0f);
  for (const Vec3& p : nearest_sorted) cog += p;
  cog = cog * (1.0f / float(k));
  const float r = Length(nearest_sorted.back() - x);
  if (!(r > 0.0f)) return k;
  const float d = Length(cog - x) / r;
  const float d0 = 2.0f / std::sqrt(float(k));
  const float d1 = 4.0f / (3.0f * kPi);
  if (d <= d0 || d0 >= d1) return k;
  if (d >= d1) return k_min;
  const float t = (d - d0) / (d1 - d0);
  return std::max(k_min, int(std::lround(float(k) - float(k - k_min) * t)));
}

RadianceEstimateResult EstimateRadiance(const PhotonMap& map, const Bsdf& bsdf, const Vec3& x, const Vec3& wo,
                                        uint32_t lobes, const RadianceEstimateOptions& options,
                                        NearestPhotons& nearest, const EstimateContext& context) {
  RadianceEstimateResult result;
  if (map.empty() || options.k <= 0) return result;
  // The viewer's side of the surface: photons must arrive from it (unless light can also
  // diffuse through the surface from the other side).
  const Vec3& ng = bsdf.geometric_normal();
  const Vec3 side = Dot(wo, ng) >= 0.0f ? ng : -ng;
  const bool two_sided = !bsdf.material().diffuse_transmittance.IsBlack();
  const bool test = options.direction_test != FeasibilityTest::kNone && !two_sided;

  auto feasible = [&side](const Photon& p) { return Dot(p.Direction(), side) > 0.0f; };
  const auto filter = FunctionFilter([&](const Photon& p, std::size_t) { return feasible(p); });
  const bool in_query = test && options.direction_test == FeasibilityTest::kInQuery;
  if (options.radius_query)
    map.QueryRadius(x, options.max_radius, nearest, in_query ? &filter : nullptr);
  else
    map.QueryWithHint(x, options.k, options.max_radius, context.radius_hint, nearest,
                      in_query ? &filter : nullptr);

  if (nearest.empty()) return result;
  if (!options.radius_query && options.min_fraction > 0.0f &&
      float(nearest.size()) < options.min_fraction * float(options.k))
    return result;

  // Entries [first, used_end) are summed over a radius² r2. Without adaptive k the heap order
  // is enough: its first entry is the farthest photon (at r), the one excluded from the sum.
  // Adaptive k needs distance order (sorting k entries costs about as much as the query).
  const bool full = nearest.full() && !options.radius_query;
  size_t first = 0, used_end = nearest.size();
  float r2 = nearest.MaxDistanceSquared();
  if (options.radius_query) {
    r2 = options.max_radius * options.max_radius;  // the disk searched, whatever it holds
  } else if (options.adaptive_k_min > 0 && full) {
    nearest.Sort();
    thread_local std::vector<Vec3> positions;
    positions.clear();
    for (const auto& e : nearest.entries()) positions.push_back(map.photon(e.index).Position());
    const size_t count = size_t(AdaptiveK(x, positions, options.adaptive_k_min));
    r2 = nearest[count - 1].distance2;
    used_end = options.exclude_boundary_photon ? count - 1 : count;
  } else if (options.exclude_boundary_photon && full) {
    first = 1;  // the heap's front
  } else if (!full && std::isfinite(options.max_radius)) {
    // Fewer than k within the bound: the whole disk of radius max_radius was searched and
    // holds exactly these photons, so it is the area to divide by. The farthest photon's
    // distance r_n would bias the estimate high: for n uniform photons E[R²/r_n²] = n/(n−1)
    // (+11 % at the caustic threshold n = 10, unbounded at n = 1).
    r2 = options.max_radius * options.max_radius;
  }
  if (!(r2 > 0.0f)) return result;  // all photons exactly at x: no area to divide by
  const auto all = nearest.entries();

  const bool after_query = test && options.direction_test == FeasibilityTest::kAfterQuery;
  const bool occlusion = options.occlusion_test && context.origins && context.scene;
  const Material& m = bsdf.material();
  // A GGX lobe (Material::microfacet) is never Lambertian, whatever specular_roughness says.
  const bool lambertian_only =
      m.microfacet == Material::Microfacet::kNone
          ? !(lobes & kLobeGlossyReflection) || m.specular_reflectance.IsBlack() ||
                m.specular_roughness <= 0.0f
          : !bsdf.HasLobes(lobes & (kLobeGlossyReflection | kLobeGlossyTransmission));
  const float reach = kOcclusionReach * std::sqrt(r2);  // the occlusion test's, below
  Rgb front(0.0f), back(0.0f), sum(0.0f);
  int used = 0;
  for (size_t i = first; i < used_end; ++i) {
    const Photon& p = map.photon(all[i].index);
    const Vec3 dir = p.Direction();
    const bool same_side = Dot(dir, side) > 0.0f;
    if (after_query && !same_side) continue;
    if (occlusion) {
      // §4.1.1, near the photon: is the photon's incoming path visible from x where it ends,
      // within kOcclusionReach radii of the photon (its origin, when nearer)? That path lies on
      // the photon's side of any wall, so a wall between x and the photon still cuts the ray (no
      // light bleeding), while an occluder far along the path no longer does: a ray from x to a
      // distant origin misses a narrow opening the photon came through. The origin is stored off
      // its surface on the side the photon left (TracedPhoton::origin), so the ray runs all the
      // way: from that side it ends short of the surface, from behind a wall of no thickness it
      // crosses it. Together they took INVISIBLEDATE from 1.4 % dark with bright seams to its
      // reference's mean (docs/results/occlusion-test.md). x is moved off its surface towards the
      // viewer — or, on a diffusely transmitting surface, towards the target's side (light from
      // behind is real there). The one origin the ray can end on exactly is a point light placed
      // exactly on a surface, within the reach.
      const Vec3& origin = (*context.origins)[all[i].index];
      const Vec3 incoming = origin - p.Position();
      const float incoming_length = Length(incoming);
      const Vec3 target =
          incoming_length > reach ? p.Position() + incoming * (reach / incoming_length) : origin;
      const Vec3 from_side = two_sided && Dot(target - x, ng) * Dot(side, ng) < 0.0f ? -side : side;
      const Vec3 from = OffsetRayOrigin(x, from_side, context.scene->epsilon());
      const Vec3 d = target - from;
      const float dist = Length(d);
      if (dist > 0.0f) {
        ++result.shadow_rays;
        if (context.scene->Occluded(Ray{from, d / dist, dist})) continue;
      }
    }
    if (lambertian_only) {
      // f_r is ρd/π on the viewer's side and τd/π on the other: sum powers, multiply once.
      (same_side ? front : back) += p.Power();
    } else {
      sum += bsdf.EvalLobes(wo, dir, lobes) * p.Power();
    }
    ++used;
  }
  if (lambertian_only) {
    sum = bsdf.EvalLobes(wo, side, lobes) * front;
    if (!back.IsBlack()) sum += bsdf.EvalLobes(wo, -side, lobes) * back;
  }
  result.radiance = sum * (1.0f / (kPi * r2));
  result.photons_used = used;
  result.radius2 = r2;
  return result;
}

}  // namespace pf
