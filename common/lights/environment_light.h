#pragma once
// The environment as a light (docs/renderer.md, "Environment light"): importance sampling of its
// directions and the power its photons carry.
//
// Distribution: piecewise constant over the image's cells (scene/environment.h), each cell chosen
// with probability ∝ luminance(L) × its solid angle — a marginal over rows (∝ Σ_j lum_ij ·
// (z_i − z_{i+1})), a conditional per row (∝ lum_ij) — then a direction uniform within the cell
// (cos θ uniform in [z_{i+1}, z_i], φ uniform in the column). So pdf(ω) = P_i·P_j|i / Δω_ij,
// exactly ∝ the luminance of the cell seen: the continuous form of the usual luminance × sin θ
// weighting (pbrt's pdf_uv/(2π² sin θ)), with each row's exact solid angle z_i − z_{i+1} in
// place of sin θ at its centre, which leaves no pdf singularity at the poles and makes a
// constant environment (one 1x1 cell) uniform over the sphere, pdf 1/(4π).
//
// Photons (photon_tracer.cpp): direction ω by the same distribution, a point uniform on the
// disc of radius R (the scene's bounding sphere) perpendicular to ω, outside the sphere, power
// L(ω)·π·R² / (pdf(ω)·p_select·N): on average π·R²·∫L dω / (p_select·N), the flux through that
// disc, i.e. every ray that can reach the scene.

#include <vector>

#include "common/core/math.h"
#include "common/scene/environment.h"

namespace pf {

class EnvironmentLight {
 public:
  // `centre` and `radius`: the scene's bounding sphere (photon emission, power).
  EnvironmentLight(const Environment& environment, const Vec3& centre, float radius);

  struct DirectionSample {
    Vec3 wi;  // unit world direction towards the sky
    Rgb radiance;
    float pdf = 0;  // solid angle
  };
  // A direction by the distribution from two uniforms in [0,1).
  DirectionSample Sample(float u1, float u2) const;
  // Solid-angle density of Sample producing unit world direction wi.
  float Pdf(const Vec3& wi) const;
  Rgb Radiance(const Vec3& wi) const { return environment_.Radiance(wi); }

  // ∫ L dω over the sphere (RGB, W/m²) and the power π·R²·∫ L dω (W) the photons carry.
  const Rgb& integrated_radiance() const { return integrated_; }
  const Rgb& power() const { return power_; }
  const Vec3& centre() const { return centre_; }
  float radius() const { return radius_; }
  uint32_t light() const { return environment_.light; }

 private:
  // Index i of the piece of a 1-D CDF (cdf[0] = 0 .. cdf[n] = 1) holding u, and u remapped to
  // [0,1) within it.
  static int Piece(const float* cdf, int n, float u, float* remapped);

  Environment environment_;
  Vec3 centre_;
  float radius_;
  int width_, height_;
  std::vector<float> row_cdf_;     // height + 1 entries
  std::vector<float> column_cdf_;  // per row, width + 1 entries
  Rgb integrated_, power_;
};

}  // namespace pf
