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
  for (size_t i = first; i < entries.size(); ++i) {
    const Photon& p = map.photon(entries[i].index);
    if (after_query && !feasible(p)) continue;
    const Rgb f = bsdf.EvalLobes(wo, p.Direction(), lobes);
    sum += f * p.Power();
    ++used;
  }
  result.radiance = sum * (1.0f / (kPi * r2));
  result.photons_used = used;
  result.radius2 = r2;
  return result;
}

}  // namespace pf
