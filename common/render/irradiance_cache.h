#pragma once
// Irradiance caching for the local pass (Wald 1999, §4.3 final gathering; Ward, Rubinstein &
// Clear 1988, "A Ray Tracing Solution for Diffuse Interreflection"; Ward & Heckbert 1992).
//
// A record holds the irradiance a full gather measured at a point x_i with normal n_i and the
// harmonic mean distance R_i of its gather hits (how far the hemisphere's geometry is: how fast
// the irradiance can change). At x with normal n, record i is usable when
//     ε_i(x, n) = |x − x_i| / R_i + sqrt(1 − n·n_i)  <  a      (a = the error parameter)
// and x_i is not in front of x (Ward 1988: a record whose point lies above x's tangent plane
// sees geometry x may not see). The estimate is the mean of the usable records weighted by
// w_i = 1/ε_i (the Ward 1988 weight, without the irradiance gradients of the 1992 paper:
// docs/renderer.md says why). No usable record → the caller gathers and adds a record.
//
// Determinism: a cache lives for one block of pixels that one thread renders in a fixed order
// (RenderPixels' pixel blocks, renderer.h), so its records depend only on the block's pixels,
// their samples and the job's seeds — never on threads or workers.
//
// Lookup: record i can only be usable within a·R_i of x_i, so records are filed in a hashed grid
// per radius level (level L holds R_i in [2^L, 2^{L+1}) · the smallest radius, with cells of
// a · 2^{L+1} · that radius: a record covers at most 3 cells per axis) and a lookup reads one cell
// per level. The usable candidates are summed in record order, so the result is bit-identical to
// a scan over all records (test: IrradianceCache.GridLookupEqualsTheLinearScan) — without the
// scan's cost, which grew with records × lookups, i.e. quadratically with the samples per block.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

#include "common/core/math.h"
#include "common/render/integrator.h"

namespace pf {

struct IrradianceCacheOptions {
  float error = 0.0f;  // Ward's a; 0 = no cache
  // R_i is clamped to [min_radius, max_radius] (absolute scene units): a record next to a wall
  // would otherwise cover nothing (R_i → 0, a gather per sample), and one in an open space
  // everything. PhotonMapIntegrator derives them from the scene diagonal when left at 0
  // (kIrradianceCacheMinRadiusFraction, kIrradianceCacheMaxRadiusFraction).
  float min_radius = 0.0f;
  float max_radius = 0.0f;
};

inline constexpr float kIrradianceCacheMinRadiusFraction = 0.01f;
inline constexpr float kIrradianceCacheMaxRadiusFraction = 0.25f;

struct IrradianceRecord {
  Vec3 position;
  Vec3 normal;          // unit, on the side the gather rays left
  Rgb irradiance;       // E/π: the mean radiance of the gather rays (white Lambertian weights)
  float radius = 0.0f;  // R_i, clamped
};

class IrradianceCache {
 public:
  explicit IrradianceCache(const IrradianceCacheOptions& options) : options_(options) {}

  // Weighted mean E/π of the records usable at (x, n) (header comment); nullopt if none is.
  // Not thread-safe (scratch space): a cache belongs to one pixel block, rendered by one thread.
  std::optional<Rgb> Interpolate(const Vec3& x, const Vec3& n) const;
  // The same from a scan over every record (the definition; tests compare the two).
  std::optional<Rgb> InterpolateLinearScan(const Vec3& x, const Vec3& n) const;
  // A record from a gather at (x, n): `irradiance` = E/π, `inverse_distance_sum` = Σ 1/d_j over
  // the gather rays that hit something (misses count as infinitely far), `hits` of them.
  void Add(const Vec3& x, const Vec3& n, const Rgb& irradiance, double inverse_distance_sum, int hits);

  const std::vector<IrradianceRecord>& records() const { return records_; }
  const IrradianceCacheOptions& options() const { return options_; }

 private:
  // Record i's contribution to the weighted mean at (x, n), or false if it is not usable.
  bool Usable(const IrradianceRecord& r, const Vec3& x, const Vec3& n, float& weight) const;
  int LevelOf(float radius) const;
  float CellSize(int level) const;

  IrradianceCacheOptions options_;
  std::vector<IrradianceRecord> records_;
  std::unordered_map<uint64_t, std::vector<uint32_t>> cells_;  // (level, cell) hash → record indices
  uint32_t levels_used_ = 0;                                   // bit L: level L holds a record
  mutable std::vector<uint32_t> candidates_;                   // Interpolate's scratch
};

// One cache per pixel block (PixelBlockState, integrator.h).
struct IrradianceCacheBlock final : PixelBlockState {
  explicit IrradianceCacheBlock(const IrradianceCacheOptions& options) : cache(options) {}
  IrradianceCache cache;
};

}  // namespace pf
