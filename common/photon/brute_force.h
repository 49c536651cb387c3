#pragma once
// Brute-force k nearest photons: the reference the photon maps are tested and benchmarked
// against. O(N) per query. Same semantics as PhotonMap::Query (photon_map.h): open ball of
// radius max_radius, in-query filter, distances from DistanceSquared.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <vector>

#include "common/photon/photon_map.h"

namespace pf {

// The min(k, #candidates) nearest accepted photons, sorted by (distance², index).
inline std::vector<NearestPhotons::Entry> BruteForceNearest(std::span<const Photon> photons, const Vec3& x,
                                                            int k, float max_radius,
                                                            const PhotonFilter* filter = nullptr) {
  std::vector<NearestPhotons::Entry> all;
  if (k <= 0 || !IsFinite(x) || !(max_radius > 0.0f)) return all;
  const float radius2 = max_radius * max_radius;
  for (std::size_t i = 0; i < photons.size(); ++i) {
    const float d2 = DistanceSquared(photons[i], x);
    if (d2 < radius2 && (filter == nullptr || filter->Accept(photons[i], i)))
      all.push_back({uint32_t(i), d2});
  }
  const auto by_distance = [](const NearestPhotons::Entry& a, const NearestPhotons::Entry& b) {
    return a.distance2 < b.distance2 || (a.distance2 == b.distance2 && a.index < b.index);
  };
  const std::size_t keep = std::min(all.size(), std::size_t(k));
  std::partial_sort(all.begin(), all.begin() + std::ptrdiff_t(keep), all.end(), by_distance);
  all.resize(keep);
  return all;
}

}  // namespace pf
