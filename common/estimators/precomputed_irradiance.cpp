#include "common/estimators/precomputed_irradiance.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <vector>

#include "common/photon/bucket_kdtree.h"

namespace pf {
namespace {

struct Site {
  Vec3 position;
  Vec3 normal;  // lit side; zero if the normal ray missed (site dropped)
  Rgb irradiance;
};

// The white Lambertian material the site estimates are read through (E = π · L).
const Material& WhiteMaterial() {
  static const Material white = [] {
    Material m;
    m.name = "precomputed-irradiance-white";
    m.diffuse_reflectance = Rgb(1.0f);
    return m;
  }();
  return white;
}

}  // namespace

std::shared_ptr<const PrecomputedIrradiance> PrecomputedIrradiance::Build(
    const EmbreeScene& scene, const PhotonMaps& maps, const PrecomputedIrradianceOptions& options,
    const RadianceFn& radiance) {
  if (options.stride < 1) throw std::invalid_argument("PrecomputedIrradiance: stride must be >= 1");
  const auto start = std::chrono::steady_clock::now();
  // Sites: every stride-th photon of the maps whose light a gather hit reads as diffuse
  // irradiance from stored photons (global, and direct when separate).
  std::vector<Photon> candidates;
  for (const PhotonMap* map : {maps.global.get(), maps.direct.get()}) {
    if (map == nullptr) continue;
    for (std::size_t i = 0; i < map->size(); i += std::size_t(options.stride))
      candidates.push_back(map->photon(i));
  }
  std::vector<Site> sites(candidates.size());
  const float delta = std::max(1e-4f * Length(scene.bounds().Diagonal()), 16.0f * scene.epsilon());
  auto compute = [&](std::size_t i) {
    const Photon& p = candidates[i];
    const Vec3 x = p.Position();
    const Vec3 w = p.Direction();  // towards where the photon came from: the lit side
    Site& s = sites[i];
    s.position = x;
    s.normal = Vec3(0.0f);
    // The surface the photon was stored on, found again: a short ray through x the way the
    // photon arrived.
    Ray ray{x + w * delta, -w, 2.0f * delta};
    const std::optional<SurfaceHit> hit = scene.Intersect(ray);
    if (!hit) return;
    const Vec3 ng = Dot(hit->geometric_normal, w) >= 0.0f ? hit->geometric_normal : -hit->geometric_normal;
    const Vec3 ns = Dot(hit->shading_normal, ng) >= 0.0f ? hit->shading_normal : -hit->shading_normal;
    const Bsdf white(WhiteMaterial(), ns, ng);
    s.normal = ns;
    s.irradiance = radiance(white, x, ns) * kPi;
  };
  auto run = [&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, sites.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                        for (std::size_t i = r.begin(); i < r.end(); ++i) compute(i);
                      });
  };
  if (options.threads > 0) {
    tbb::task_arena arena(options.threads);
    arena.execute(run);
  } else {
    run();
  }

  auto out = std::make_shared<PrecomputedIrradiance>();
  BucketKdOptions bucket;
  bucket.split = BucketSplit::kMidpoint;
  bucket.leaf_size = 16;
  out->sites_ = std::make_unique<BucketKdTree>(bucket);
  out->sites_->Reserve(sites.size());
  for (const Site& s : sites)
    if (Dot(s.normal, s.normal) > 0.0f) out->sites_->AddPhoton(s.position, s.normal, s.irradiance);
  out->sites_->PrepareForQuery();
  out->normal_cos_ = options.normal_cos;
  out->scene_ = &scene;
  out->candidates_ = options.candidates;
  out->average_ = std::max(options.average, 1);
  out->max_radius_ = std::max(options.max_radius_fraction * Length(scene.bounds().Diagonal()), 1e-12f);
  out->build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

std::optional<Rgb> PrecomputedIrradiance::Lookup(const Vec3& y, const Vec3& n,
                                                 NearestPhotons& nearest) const {
  if (sites_->empty()) return std::nullopt;
  const float min_cos = normal_cos_;
  const auto agrees = FunctionFilter(
      [&n, min_cos](const Photon& p, std::size_t) { return Dot(p.Direction(), n) >= min_cos; });
  sites_->Query(y, std::max(candidates_, 1), max_radius_, nearest, &agrees);
  if (nearest.empty()) return std::nullopt;
  nearest.Sort();
  if (candidates_ == 0) return sites_->photon(nearest[0].index).Power();
  // Both ends leave their surfaces on their lit sides, n and the site's normal (§4.1.1's
  // occlusion test between two surface points). EmbreeScene::Visible picks each side by the sign
  // of the direction to the other end instead, and for y and a site on one plane that sign is
  // the rounding of their coordinates (photons lie within an ulp of their plane, on either side):
  // one end then sat behind the plane and the ray crossed it, so coplanar candidates were
  // "occluded" about half the time (INVISIBLEDATE: 22 % of the lookups fell back to the full
  // estimate, mostly on the shared wall, at 30-170 us each; docs/results/kernel.md §2).
  const float eps = scene_->epsilon();
  const Vec3 from = OffsetRayOrigin(y, n, eps);
  // The mean of the first `average` visible candidates, in distance order (ties by index: the
  // same sum for any thread count).
  Rgb sum(0.0f);
  int found = 0;
  for (std::size_t i = 0; i < nearest.size() && found < average_; ++i) {
    const Photon& site = sites_->photon(nearest[i].index);
    const Vec3 to = OffsetRayOrigin(site.Position(), site.Direction(), eps);
    const Vec3 d = to - from;
    const float dist = Length(d);
    if (!(dist > 0.0f) || !scene_->Occluded(Ray{from, d / dist, dist})) {
      sum += site.Power();
      ++found;
    }
  }
  if (found == 0) return std::nullopt;
  return found == 1 ? sum : sum * (1.0f / float(found));
}

}  // namespace pf
