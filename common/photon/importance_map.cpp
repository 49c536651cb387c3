#include "common/photon/importance_map.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <vector>

#include "common/accel/embree_scene.h"
#include "common/core/rng.h"
#include "common/materials/bsdf.h"
#include "common/photon/photon_map_factory.h"
#include "common/sampling/sample_layout.h"
#include "common/scene/surface_material.h"

namespace pf {

const char* ImportanceModeName(ImportanceMode mode) {
  switch (mode) {
    case ImportanceMode::kOn:
      return "on";
    case ImportanceMode::kAuto:
      return "auto";
    default:
      return "off";
  }
}

uint64_t ImportonStreamSeed(uint64_t seed) {
  return HashKey(seed, 0x696d706f72746f6eull);  // "importon"
}

namespace {

constexpr uint64_t kImportonChunk = 4096;  // fixed, so the output order is fixed
// Importons whose importance is averaged into Ī at most (every m-th one): bounds the build's
// queries; the mean of 16k estimates is far more precise than the acceptance needs.
constexpr uint64_t kMeanSamples = 16384;

// The geometric normal on the side direction `wo` points to.
Vec3 Facing(const SurfaceHit& hit, const Vec3& wo) {
  return Dot(hit.geometric_normal, wo) >= 0.0f ? hit.geometric_normal : -hit.geometric_normal;
}

void TraceImporton(const EmbreeScene& scene, const Camera& camera, const ImportanceOptions& o,
                   uint64_t stream, SamplerKind kind, uint64_t index, uint64_t count,
                   std::vector<Photon>& out) {
  const SceneDescription& desc = scene.description();
  Sampler sampler = Sampler::ForPhoton(kind, stream, index);
  const Sample2 u_image = sampler.Get2D(kImportonImageSlot);
  const float fx = u_image.u * float(camera.width()), fy = u_image.v * float(camera.height());
  const int px = std::min(int(fx), camera.width() - 1), py = std::min(int(fy), camera.height() - 1);
  Ray ray = camera.GenerateRay(px, py, fx - float(px), fy - float(py));
  float weight = 1.0f / float(count);
  int diffuse_left = o.diffuse_bounces;
  for (int bounce = 0; bounce < 64; ++bounce) {
    const std::optional<SurfaceHit> hit = scene.Intersect(ray);
    if (!hit) return;
    std::optional<Material> textured;  // filled only for a textured material
    const Material& m = MaterialAt(desc, hit->material, hit->uv, &textured);
    const Bsdf bsdf(m, hit->shading_normal, hit->geometric_normal);
    const Vec3 wo = -ray.direction;
    if (bsdf.HasDiffuse()) {
      out.push_back(Photon::Make(hit->position, Facing(*hit, wo), Rgb(weight)));
      if (diffuse_left-- <= 0) return;
    }
    const PhotonBounceSlots slots = SlotsOfImportonBounce(bounce);
    const float ul = sampler.Get1D(slots.lobe);
    const Sample2 u = sampler.Get2D(slots.direction);
    const std::optional<BsdfSample> s = bsdf.Sample(wo, ul, u.u, u.v, Bsdf::Mode::kRussianRoulette);
    if (!s) return;
    // Importance is carried like the photons' power, as one number (the channels' mean).
    weight *= (s->weight.r + s->weight.g + s->weight.b) / 3.0f;
    if (!(weight > 0.0f) || !std::isfinite(weight)) return;
    ray = Ray{scene.SpawnOrigin(*hit, s->wi), s->wi};
  }
}

// Density of the importons facing `facing` around x: Σ w / (π r²) over the k nearest.
float Density(const PhotonMap& map, const Vec3& x, const Vec3& facing, int k, float max_radius,
              ImportanceScratch& scratch) {
  const auto same_side =
      FunctionFilter([&](const Photon& p, std::size_t) { return Dot(p.Direction(), facing) > 0.0f; });
  map.Query(x, k, max_radius, scratch, &same_side);
  if (scratch.empty()) return 0.0f;
  float sum = 0.0f;
  for (const NearestPhotons::Entry& e : scratch.entries()) sum += map.photon(e.index).Power().r;
  const float r2 = scratch.full() ? std::max(scratch.MaxDistanceSquared(), 1e-30f) : max_radius * max_radius;
  return sum / (kPi * r2);
}

}  // namespace

ImportanceMap ImportanceMap::Build(const EmbreeScene& scene, const Camera& camera,
                                   const ImportanceOptions& options, uint64_t seed, SamplerKind sampler,
                                   int threads) {
  const auto start = std::chrono::steady_clock::now();
  ImportanceMap map;
  map.options_ = options;
  map.options_.k = std::max(1, options.k);
  const uint64_t count =
      options.importons > 0 ? options.importons : uint64_t(camera.width()) * uint64_t(camera.height());
  map.stats_.traced = count;
  // Far enough to bridge the gaps between importons on distant surfaces, near enough that
  // a room the camera does not see finds none (0.05 of the scene's diagonal).
  map.max_radius_ = 0.05f * std::max(Length(scene.bounds().Diagonal()), 1e-20f);
  const uint64_t stream = ImportonStreamSeed(seed);
  const uint64_t chunks = (count + kImportonChunk - 1) / kImportonChunk;
  std::vector<std::vector<Photon>> outputs(chunks);
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_for(uint64_t(0), chunks, [&](uint64_t c) {
      const uint64_t end = std::min(count, (c + 1) * kImportonChunk);
      for (uint64_t i = c * kImportonChunk; i < end; ++i)
        TraceImporton(scene, camera, map.options_, stream, sampler, i, count, outputs[c]);
    });
  });
  map.importons_ = MakePhotonMap(PhotonMapKind::kKdTree, PhotonMapOptions{});
  map.importons_->set_build_threads(threads);
  for (const std::vector<Photon>& out : outputs) map.importons_->AddPhotons(out);
  map.importons_->PrepareForQuery();
  map.stats_.stored = map.importons_->size();
  if (map.stats_.stored > 0) {
    // Ī: the importance at (every m-th) stored importon, summed in order (thread-independent).
    const uint64_t n = map.stats_.stored, stride = std::max<uint64_t>(1, n / kMeanSamples);
    const uint64_t samples = (n + stride - 1) / stride;
    std::vector<float> density(samples);
    arena.execute([&] {
      tbb::parallel_for(uint64_t(0), samples, [&](uint64_t j) {
        thread_local ImportanceScratch scratch;
        const Photon& p = map.importons_->photon(j * stride);
        density[j] =
            Density(*map.importons_, p.Position(), p.Direction(), map.options_.k, map.max_radius_, scratch);
      });
    });
    double sum = 0;
    for (float d : density) sum += d;
    map.stats_.mean_importance = sum / double(samples);
    if (map.stats_.mean_importance > 0) map.inverse_mean_ = float(1.0 / map.stats_.mean_importance);
  }
  // The acceptance table's grid (see the header): cells of max_radius/8, coarser if the scene
  // would need more than kMaxCells of them.
  const Bounds3& b = scene.bounds();
  const Vec3 extent = Max(b.Diagonal(), Vec3(1e-20f));
  float cell = map.max_radius_ / 8.0f;
  const double volume = double(extent.x) * double(extent.y) * double(extent.z);
  cell = std::max(cell, float(std::cbrt(volume / double(kMaxCells))) * 1.01f);
  for (;;) {
    uint64_t cells = 1;
    for (int a = 0; a < 3; ++a) {
      map.dims_[a] = std::max(1, int(std::ceil(extent[a] / cell)));
      cells *= uint64_t(map.dims_[a]);
    }
    if (cells <= kMaxCells) {
      map.table_ = std::make_unique<std::atomic<float>[]>(6 * cells);
      for (uint64_t i = 0; i < 6 * cells; ++i) map.table_[i].store(-1.0f, std::memory_order_relaxed);
      break;
    }
    cell *= 1.25f;
  }
  map.cell_ = cell;
  map.grid_origin_ = b.lo;
  map.stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return map;
}

float ImportanceMap::RelativeImportance(const Vec3& x, const Vec3& facing, ImportanceScratch& scratch) const {
  if (!importons_ || importons_->empty()) return 0.0f;
  return Density(*importons_, x, facing, options_.k, max_radius_, scratch) * inverse_mean_;
}

float ImportanceMap::AcceptanceProbability(const Vec3& x, const Vec3& facing,
                                           ImportanceScratch& scratch) const {
  if (!importons_ || importons_->empty() || !(inverse_mean_ > 0.0f)) return 1.0f;
  if (!table_ || !IsFinite(x)) return ExactAcceptanceProbability(x, facing, scratch);
  uint64_t index = 0;
  Vec3 centre;
  for (int a = 0; a < 3; ++a) {
    const int i = std::clamp(int((x[a] - grid_origin_[a]) / cell_), 0, dims_[a] - 1);
    index = index * uint64_t(dims_[a]) + uint64_t(i);
    centre[a] = grid_origin_[a] + (float(i) + 0.5f) * cell_;
  }
  const Vec3 mag(std::fabs(facing.x), std::fabs(facing.y), std::fabs(facing.z));
  const int axis = mag.x >= mag.y && mag.x >= mag.z ? 0 : (mag.y >= mag.z ? 1 : 2);
  const bool negative = facing[axis] < 0.0f;
  std::atomic<float>& entry = table_[6 * index + uint64_t(2 * axis + (negative ? 1 : 0))];
  float p = entry.load(std::memory_order_relaxed);
  if (p < 0.0f) {
    Vec3 normal(0.0f);
    normal[axis] = negative ? -1.0f : 1.0f;
    p = ExactAcceptanceProbability(centre, normal, scratch);
    entry.store(p, std::memory_order_relaxed);
  }
  return p;
}

float ImportanceMap::ExactAcceptanceProbability(const Vec3& x, const Vec3& facing,
                                                ImportanceScratch& scratch) const {
  if (!importons_ || importons_->empty() || !(inverse_mean_ > 0.0f)) return 1.0f;
  const float p = options_.strength * RelativeImportance(x, facing, scratch);
  return std::clamp(p, options_.min_probability, 1.0f);
}

}  // namespace pf
