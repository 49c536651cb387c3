#include "common/estimators/radiance_estimate.h"

namespace pf {

RadianceEstimateResult EstimateRadiance(const PhotonMap& map, const Bsdf& bsdf, const Vec3& x,
                                        const Vec3& wo, uint32_t lobes,
                                        const RadianceEstimateOptions& options,
                                        NearestPhotons& nearest) {
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
  map.Query(x, options.k, options.max_radius, nearest, in_query ? &filter : nullptr);

  const int found = int(nearest.size());
  if (found == 0) return result;
  if (options.min_fraction > 0.0f && float(found) < options.min_fraction * float(options.k)) return result;
  const float r2 = nearest.MaxDistanceSquared();
  if (!(r2 > 0.0f)) return result;  // all photons exactly at x: no area to divide by

  const bool after_query = test && options.direction_test == FeasibilityTest::kAfterQuery;
  Rgb sum(0.0f);
  int used = 0;
  // The heap's first entry is the farthest photon, the one at distance r.
  const auto entries = nearest.entries();
  const size_t first = options.exclude_boundary_photon && nearest.full() ? 1 : 0;
  const Material& m = bsdf.material();
  const bool lambertian_only = !(lobes & kLobeGlossyReflection) || m.specular_reflectance.IsBlack() ||
                               m.specular_roughness <= 0.0f;
  if (lambertian_only) {
    // Fast path: f_r is ρd/π for photons arriving on the viewer's side and τd/π for the
    // other side, so the powers are summed per side and multiplied once (no per-photon BSDF).
    Rgb front(0.0f), back(0.0f);
    for (size_t i = first; i < entries.size(); ++i) {
      const Photon& p = map.photon(entries[i].index);
      const bool same_side = Dot(p.Direction(), side) > 0.0f;
      if (after_query && !same_side) continue;
      (same_side ? front : back) += p.Power();
      ++used;
    }
    const Rgb f_front = bsdf.EvalLobes(wo, side, lobes);
    const Rgb f_back = back.IsBlack() ? Rgb(0.0f) : bsdf.EvalLobes(wo, -side, lobes);
    sum = f_front * front + f_back * back;
  } else {
    for (size_t i = first; i < entries.size(); ++i) {
      const Photon& p = map.photon(entries[i].index);
      if (after_query && !feasible(p)) continue;
      sum += bsdf.EvalLobes(wo, p.Direction(), lobes) * p.Power();
      ++used;
    }
  }
  result.radiance = sum * (1.0f / (kPi * r2));
  result.photons_used = used;
  result.radius2 = r2;
  return result;
}

}  // namespace pf
