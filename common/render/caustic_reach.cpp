#include "common/render/caustic_reach.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "common/lights/light_choice.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_tracer.h"
#include "common/render/path_tracer.h"
#include "common/render/pilot_lattice.h"
#include "common/render/progressive_radius.h"
#include "common/sampling/hashed_uniform.h"

namespace pf {
namespace {

// Perfect mirrors and glass a photon (or a camera ray) is followed through, at most this many in a
// row: a glass ball is two, a glass in a mirror four; light after eight more is a sliver of the
// caustic, and the pilot must stay cheap.
constexpr int kMaxSpecularChain = 8;
constexpr uint32_t kDeltaLobes = kLobeSpecularReflection | kLobeSpecularTransmission;
// The caustic photons' kernel holds about this many photons of the pilot's, were they spread
// evenly over the surface of the scene's bounding box (DerivedInitialRadius).
constexpr int kKernelPhotons = 64;

// A pilot photon that reached a surface with a diffuse lobe through one or more delta lobes, from
// an emitting triangle or the environment (luminances).
struct CausticPhoton {
  Vec3 position;
  Vec3 direction;           // of travel
  float power = 0;          // Φ
  float path_radiance = 0;  // T·Le: what a path tracer's ray along it back to the light brings
};

struct LightSide {
  double landed = 0, punctual_caustic = 0;
  std::vector<CausticPhoton> caustics;
};

// Photons as TracePhotons emits them (LaunchPhoton, a stratified light choice ∝ power), each
// followed through delta lobes; every surface with a diffuse lobe on the way is a landing.
LightSide TraceLightSide(const SceneRuntime& scene, int photons) {
  const SceneDescription& desc = scene.description;
  LightSide all;
  if (photons <= 0 || scene.lights.empty()) return all;
  const std::vector<PhotonEmitter> emitters = PhotonEmitters(desc, scene.lights, uint64_t(photons));
  const EnvironmentLight* environment = scene.lights.environment();
  constexpr int kBlocks = 64;
  std::vector<LightSide> blocks(kBlocks);
  tbb::parallel_for(0, kBlocks, [&](int b) {
    LightSide& out = blocks[size_t(b)];
    for (int p = b; p < photons; p += kBlocks) {
      const uint64_t cell = uint64_t(p);
      const float u_select = (float(p) + HashedUniform(cell, 0, 0)) / float(photons);
      const size_t emitter = scene.lights.EmitterIndex(u_select);
      const PhotonEmitter& em = emitters[emitter];
      const Sample2 u_point{HashedUniform(cell, 0, 1), HashedUniform(cell, 0, 2)};
      const PhotonLaunch launch = LaunchPhoton(
          em, u_point, {HashedUniform(cell, 0, 3), HashedUniform(cell, 0, 4)}, scene.accel.epsilon());
      const bool punctual = em.punctual && !em.environment;
      const float emitted = launch.power.Luminance();
      if (!(emitted > 0.0f)) continue;
      // Le along the photon's way back: the environment's in its direction, a triangle's at its point.
      float radiance = 0.0f;
      if (em.environment) {
        radiance = environment->Radiance(-launch.ray.direction).Luminance();
      } else if (!punctual) {
        radiance = scene.lights.EmitterSample(emitter, u_point.u, u_point.v).radiance.Luminance();
      }
      Ray ray = launch.ray;
      Rgb power = launch.power;
      for (int chain = 0; chain <= kMaxSpecularChain; ++chain) {
        const std::optional<SurfaceHit> hit = scene.accel.Intersect(ray);
        if (!hit) break;
        const Bsdf bsdf(desc.materials[hit->material], hit->shading_normal, hit->geometric_normal);
        if (bsdf.HasDiffuse()) {
          const float l = power.Luminance();
          out.landed += l;
          if (chain > 0 && punctual) out.punctual_caustic += l;
          if (chain > 0 && !punctual)
            out.caustics.push_back({hit->position, ray.direction, l, radiance * (l / emitted)});
        }
        // Onwards by the perfect mirror and glass lobes only, also of a material that has a diffuse
        // or glossy lobe beside them (MGF rd with a smooth rs): from those lobes a path tracer's
        // shadow rays find the light. Russian roulette over the lobes keeps the photon's expected
        // power, as the photon walk does (§2.2).
        if (!bsdf.HasLobes(kDeltaLobes)) break;
        const uint64_t dim = 8 + 3 * uint64_t(chain);
        const std::optional<BsdfSample> s =
            bsdf.Sample(-ray.direction, HashedUniform(cell, 0, dim), HashedUniform(cell, 0, dim + 1),
                        HashedUniform(cell, 0, dim + 2), Bsdf::Mode::kRussianRoulette, kDeltaLobes);
        if (!s || s->weight.IsBlack()) break;
        power = power * s->weight;
        ray = Ray{scene.accel.SpawnOrigin(*hit, s->wi), s->wi};
      }
    }
  });
  for (LightSide& b : blocks) {  // in block order: the same sums and photons on every thread count
    all.landed += b.landed;
    all.punctual_caustic += b.punctual_caustic;
    all.caustics.insert(all.caustics.end(), b.caustics.begin(), b.caustics.end());
  }
  return all;
}

// The caustic photons sorted into cubic cells of side r, for the kernel's look-ups. Not a PhotonMap
// (photon_map.h, whose QueryRadius answers the same question): its 18-byte photons (§2.2) carry one
// RGBE power, and the kernel needs two per photon, Φ and T·Le·Φ, which differ by the light's
// radiance (orders of magnitude for a small lamp: one shared exponent would lose Φ).
class CausticGrid {
 public:
  CausticGrid(std::vector<CausticPhoton> photons, float r) : photons_(std::move(photons)), r_(r) {
    std::sort(photons_.begin(), photons_.end(), [this](const CausticPhoton& a, const CausticPhoton& b) {
      return Key(a.position) < Key(b.position);
    });
    keys_.reserve(photons_.size());
    for (const CausticPhoton& p : photons_) keys_.push_back(Key(p.position));
  }
  // Calls visit for every photon within r of x.
  template <typename Visit>
  void ForEachNear(const Vec3& x, const Visit& visit) const {
    const int64_t cx = Cell(x.x), cy = Cell(x.y), cz = Cell(x.z);
    for (int64_t dz = -1; dz <= 1; ++dz)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dx = -1; dx <= 1; ++dx) {
          const uint64_t key = KeyOf(cx + dx, cy + dy, cz + dz);
          const auto [first, last] = std::equal_range(keys_.begin(), keys_.end(), key);
          for (auto k = first; k != last; ++k) {
            const CausticPhoton& p = photons_[size_t(k - keys_.begin())];
            const Vec3 d = p.position - x;
            if (Dot(d, d) <= r_ * r_) visit(p);
          }
        }
  }

 private:
  int64_t Cell(float v) const { return int64_t(std::floor(double(v) / double(r_))); }
  static uint64_t KeyOf(int64_t x, int64_t y, int64_t z) {
    const auto h = [](int64_t v) { return uint64_t(v) & 0x1fffffu; };  // 21 bits per axis
    return h(x) << 42 | h(y) << 21 | h(z);
  }
  uint64_t Key(const Vec3& p) const { return KeyOf(Cell(p.x), Cell(p.y), Cell(p.z)); }
  std::vector<CausticPhoton> photons_;
  std::vector<uint64_t> keys_;
  float r_;
};

// The luminance of the irradiance at x (side n) that one light sample of `choice` estimates.
double DirectIrradiance(const SceneRuntime& scene, const LightChoice& choice, const Vec3& x, const Vec3& n,
                        float u0, float u1, float u2) {
  if (choice.empty()) return 0.0;
  const LightChoice::Choice c = choice.Choose(u0);
  if (!(c.probability > 0.0f)) return 0.0;
  const LightSample ls = scene.lights.SampleLight(c.light, c.u, u1, u2);
  if (ls.environment) {
    const float cos_x = Dot(n, ls.wi);
    const float pdf = c.probability * ls.pdf_area * ls.pdf_direction;
    if (cos_x <= 0.0f || !(pdf > 0.0f) || !scene.lights.UnoccludedTowards(x, n, ls.wi)) return 0.0;
    return double(ls.radiance.Luminance()) * cos_x / pdf;
  }
  if (ls.delta()) {
    const DeltaIncidence in = scene.lights.Incidence(ls, x);
    const float cos_x = Dot(n, in.wi);
    if (cos_x <= 0.0f || in.irradiance.IsBlack() || !scene.lights.Unoccluded(x, n, in)) return 0.0;
    return double(in.irradiance.Luminance()) * cos_x / c.probability;
  }
  const Vec3 to_light = ls.position - x;
  const float d2 = Dot(to_light, to_light);
  if (!(d2 > 0.0f) || !(ls.pdf_area > 0.0f)) return 0.0;
  const Vec3 wi = to_light * (1.0f / std::sqrt(d2));
  const float cos_x = Dot(n, wi), cos_light = -Dot(ls.normal, wi);
  if (cos_x <= 0.0f || cos_light <= 0.0f || !scene.accel.Visible(x, n, ls.position, ls.normal)) return 0.0;
  return double(ls.radiance.Luminance()) * cos_x * cos_light / (d2 * c.probability * ls.pdf_area);
}

// A point's squared relative noise counts up to this much in the mean: a single dark point with a
// caustic photon nearby must not decide for the whole image.
constexpr double kMaxRelativeVariance = 100.0;

struct CameraSums {
  int points = 0;
  double caustic = 0, total = 0, relative_variance = 0;
};

CameraSums MeasureAtCameraPoints(const SceneRuntime& scene, const Camera& camera, const CausticGrid& caustics,
                                 float r, int grid, int shadow_rays) {
  const SceneDescription& desc = scene.description;
  const LightChoice choice(scene.lights, PathTracerOptions{}.nee_uniform_fraction);
  const double kernel = 1.0 / (std::numbers::pi * double(r) * double(r));
  std::vector<CameraSums> rows(static_cast<size_t>(grid));
  tbb::parallel_for(0, grid, [&](int j) {
    CameraSums& row = rows[size_t(j)];
    for (int i = 0; i < grid; ++i) {
      const uint64_t cell = uint64_t(1) << 40 | (uint64_t(j) * uint64_t(grid) + uint64_t(i));
      // The first surface with a non-delta lobe, seen directly or through mirrors and glass (a
      // caustic seen through the glass that makes it counts too).
      Ray ray = PilotLatticeRay(camera, grid, i, j);
      std::optional<SurfaceHit> hit = scene.accel.Intersect(ray);
      for (int chain = 0; hit; ++chain) {
        const Material& m = desc.materials[hit->material];
        if (m.IsEmissive() && hit->front_face) {
          hit.reset();
          break;
        }
        const Bsdf bsdf(m, hit->shading_normal, hit->geometric_normal);
        if (bsdf.HasNonDelta()) break;
        const uint64_t dim = 3 + 3 * uint64_t(chain), sample = uint64_t(shadow_rays);
        std::optional<BsdfSample> s;
        if (chain < kMaxSpecularChain)
          s = bsdf.Sample(-ray.direction, HashedUniform(cell, sample, dim),
                          HashedUniform(cell, sample, dim + 1), HashedUniform(cell, sample, dim + 2));
        if (!s || s->weight.IsBlack()) {
          hit.reset();
          break;
        }
        ray = Ray{scene.accel.SpawnOrigin(*hit, s->wi), s->wi};
        hit = scene.accel.Intersect(ray);
      }
      if (!hit) continue;
      const Vec3 n =
          Dot(hit->geometric_normal, ray.direction) < 0.0f ? hit->geometric_normal : -hit->geometric_normal;
      double direct = 0, direct_squared = 0;
      for (int s = 0; s < shadow_rays; ++s) {
        const double d =
            DirectIrradiance(scene, choice, hit->position, n, HashedUniform(cell, uint64_t(s), 0),
                             HashedUniform(cell, uint64_t(s), 1), HashedUniform(cell, uint64_t(s), 2));
        direct += d;
        direct_squared += d * d;
      }
      // Ec, the second moment, and Σ of the photons' squared contributions: the kernel estimate's own
      // variance, which its square carries (E[Êc²] = Ec² + Var Êc, photons as a Poisson process).
      double caustic = 0, second_moment = 0, caustic_noise = 0;
      caustics.ForEachNear(hit->position, [&](const CausticPhoton& p) {
        if (Dot(n, p.direction) >= 0.0f) return;  // arrived on the other side
        const double e = kernel * p.power;
        caustic += e;
        second_moment += std::numbers::pi * double(p.path_radiance) * e;
        caustic_noise += e * e;
      });
      // The direct estimate's mean and the variance of that mean, likewise.
      const double direct_mean = shadow_rays > 0 ? direct / shadow_rays : 0.0;
      const double direct_noise =
          shadow_rays > 1
              ? std::max(0.0, direct_squared / shadow_rays - direct_mean * direct_mean) / (shadow_rays - 1)
              : 0.0;
      const double total = direct_mean + caustic;
      ++row.points;
      row.caustic += caustic;
      row.total += total;
      const double variance = std::max(0.0, second_moment - (caustic * caustic - caustic_noise));
      const double total_squared = total * total - caustic_noise - direct_noise;
      if (variance > 0.0)
        row.relative_variance += total_squared > 0.0
                                     ? std::min(variance / total_squared, kMaxRelativeVariance)
                                     : kMaxRelativeVariance;
    }
  });
  CameraSums all;
  for (const CameraSums& row : rows) {  // in row order: the same sums on every thread count
    all.points += row.points;
    all.caustic += row.caustic;
    all.total += row.total;
    all.relative_variance += row.relative_variance;
  }
  return all;
}

}  // namespace

CausticReach MeasureCausticReach(const SceneRuntime& scene, const Camera& camera, int grid, int shadow_rays,
                                 int photons) {
  CausticReach r;
  if (scene.lights.empty()) return r;
  LightSide light_side = TraceLightSide(scene, photons);
  if (light_side.landed > 0.0) r.punctual_caustic_share = light_side.punctual_caustic / light_side.landed;
  const float radius =
      float(DerivedInitialRadius(scene.accel.bounds(), uint64_t(std::max(photons, 1)), kKernelPhotons));
  const CausticGrid caustics(std::move(light_side.caustics), radius);
  const CameraSums sums = MeasureAtCameraPoints(scene, camera, caustics, radius, grid, shadow_rays);
  r.points = sums.points;
  if (sums.points > 0) r.relative_caustic_variance = sums.relative_variance / sums.points;
  if (sums.total > 0.0) r.caustic_fraction = sums.caustic / sums.total;
  return r;
}

}  // namespace pf
