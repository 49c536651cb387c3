#pragma once
// Importance-driven photon maps (Wald 1999, §4.7): an importance map built from importons
// traced from the camera, and the acceptance probability the photon tracer stores a diffuse
// photon hit with.
//
// Importons (the thesis's "importance particles", after Peter & Pietrek 1998): importon i leaves
// the camera through image position i of a 2-D sequence over the whole image (sample_layout.h,
// importon slots), follows specular and glossy bounces (Russian roulette on the BSDF, like a
// photon) and is stored at its first hit on a surface with a diffuse component, with its weight
// (1/N times the throughput of the singular bounces) and the geometric normal on the side it
// arrived from. `diffuse_bounces` > 0 lets it continue through that many diffuse bounces and be
// stored again at each (for estimators that read the map one bounce away from the visible
// points: the local pass, §4.3).
//
// The local importance at a point x on a surface facing n: the density estimate of the
// importons over the k nearest ones facing the same side (n_importon · n > 0; keeps a wall's
// viewed side from making its back side important),
//     I(x) = Σ w_i / (π r²),  r = distance of the k-th one (max_radius if fewer were found),
// and relative to the mean Ī over the importons themselves (I evaluated at each stored importon,
// averaged): the relative importance I(x)/Ī is 1 for an average visible point, 0 far from every
// importon, and independent of the number of importons and of the image's scale.
//
// Acceptance probability (the thesis's formula is garbled; this is ours):
//     p(x) = clamp(s · I(x)/Ī, p_min, 1)
// with the strength s (photons are kept with certainty wherever the importance is at least
// 1/s of the mean) and the minimum probability p_min > 0. A photon hit is stored with
// probability p(x) and power Φ/p(x). Unbiased: p depends only on the importance map, which is
// fixed before the photons are traced and independent of their random numbers, so for every
// hit E[stored power] = p·Φ/p + (1−p)·0 = Φ, and every estimate linear in the stored powers
// (a density estimate with a given radius) keeps its expectation; p_min > 0 keeps every region
// reachable. The walk itself is not changed by the decision (see photon_tracer.h).
//
// Speed: a k-nearest query per diffuse hit made photon tracing 6× slower (INVISIBLEDATE-like,
// 5M hits). The tracer therefore reads p from a lazily filled table over a regular grid of
// cells of side h = max_radius/8 (at most kMaxCells cells) and the six axis directions: the
// value of a (cell, dominant axis of the facing normal) is p at the cell's centre with that axis
// as the normal. Still a fixed function of the hit's position and side, so still unbiased, and
// deterministic: whichever thread fills an entry computes the same bits.
//
// Determinism: importon i draws from Sampler::ForPhoton(kind, ImportonStreamSeed(seed), i), the
// importons are traced in fixed chunks and concatenated in order, and the map is built like a
// photon map: the same map for any thread count.

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>

#include "common/camera/camera.h"
#include "common/photon/photon_map.h"
#include "common/sampling/sampler.h"

namespace pf {

class EmbreeScene;

enum class ImportanceMode { kOff, kOn, kAuto };

// "off" / "on" / "auto".
const char* ImportanceModeName(ImportanceMode mode);

struct ImportanceOptions {
  ImportanceMode mode = ImportanceMode::kOff;
  float min_probability = 0.05f;  // p_min in (0, 1]
  float strength = 4.0f;          // s > 0
  uint64_t importons = 0;         // 0 = one per pixel of the camera
  int diffuse_bounces = 0;        // diffuse bounces an importon continues through (local pass)
  int k = 16;                     // importons per importance estimate
};

// Limits the job-setting validation uses (proto/convert.cpp, client flags).
inline constexpr uint64_t kMaxImportons = uint64_t(1) << 26;

struct ImportanceMapStats {
  uint64_t traced = 0;  // importons shot from the camera
  uint64_t stored = 0;  // importon hits stored (0 if the camera sees no diffuse surface)
  double mean_importance = 0;
  double seconds = 0;
};

// The per-thread scratch of importance queries.
using ImportanceScratch = NearestPhotons;

class ImportanceMap {
 public:
  // Traces the importons of `seed` for `camera` (in the scene's frame) and builds the map.
  static ImportanceMap Build(const EmbreeScene& scene, const Camera& camera, const ImportanceOptions& options,
                             uint64_t seed, SamplerKind sampler, int threads);

  // I(x)/Ī at x on a surface whose normal on the side the query comes from is `facing`.
  float RelativeImportance(const Vec3& x, const Vec3& facing, ImportanceScratch& scratch) const;
  // p(x) = clamp(s · I(x)/Ī, p_min, 1). 1 everywhere if no importon was stored (nothing is
  // visible: no basis to thin anything).
  float AcceptanceProbability(const Vec3& x, const Vec3& facing, ImportanceScratch& scratch) const;
  // The exact p(x) at x (no cell table): for tests and diagnostics.
  float ExactAcceptanceProbability(const Vec3& x, const Vec3& facing, ImportanceScratch& scratch) const;
  // Cells of the table at most.
  static constexpr uint64_t kMaxCells = uint64_t(1) << 22;

  const ImportanceMapStats& stats() const { return stats_; }
  const ImportanceOptions& options() const { return options_; }
  // Stored importons (post-build order), their weight in the power's channels.
  const PhotonMap& importons() const { return *importons_; }

 private:
  std::unique_ptr<PhotonMap> importons_;
  ImportanceOptions options_;
  ImportanceMapStats stats_;
  float max_radius_ = 0.0f;
  float inverse_mean_ = 0.0f;
  // The table of p per (cell, facing axis): negative = not computed yet.
  Vec3 grid_origin_;
  float cell_ = 1.0f;
  int dims_[3] = {1, 1, 1};
  std::unique_ptr<std::atomic<float>[]> table_;
};

// The key of the importons' sampler streams for a map seed (apart from the photons' streams).
uint64_t ImportonStreamSeed(uint64_t seed);

}  // namespace pf
