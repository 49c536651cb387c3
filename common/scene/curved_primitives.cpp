// Tessellation of curved primitives (curved_primitives.h).

#include "common/scene/curved_primitives.h"

#include <cmath>
#include <numbers>

#include "common/scene/polygon_triangulation.h"

namespace pf::geometry {
namespace {

constexpr double kPiD = std::numbers::pi;
constexpr uint32_t kNone = 0xffffffffu;

// Outward triangle (a, b, c), reversed when the primitive faces inwards.
void Tri(MeshSink& sink, double sign, uint32_t a, uint32_t b, uint32_t c) {
  if (sign > 0.0) {
    sink.AddTriangle(a, b, c);
  } else {
    sink.AddTriangle(a, c, b);
  }
}

}  // namespace

UnitCircle::UnitCircle(int segments) {
  const int n = segments;
  cos_sin_.resize(static_cast<size_t>(n) + 1);
  for (int i = 0; i <= n; ++i) {
    const double a = 2.0 * kPiD * i / n;
    cos_sin_[i] = {std::cos(a), std::sin(a)};
  }
  cos_sin_[n] = cos_sin_[0];  // close the circle exactly
}

void TessellateSphere(const Vec3d& c, double rw, double sign, const UnitCircle& circle, MeshSink& sink) {
  const int n = circle.segments();
  const int bands = SphereBands(n);
  std::vector<uint32_t> ids(static_cast<size_t>(bands + 1) * n);
  for (int j = 0; j <= bands; ++j) {
    const double phi = kPiD * j / bands;  // polar angle from +z
    const double sp = (j == 0 || j == bands) ? 0.0 : std::sin(phi);
    const double cp = j == 0 ? 1.0 : (j == bands ? -1.0 : std::cos(phi));
    for (int i = 0; i < n; ++i) {
      const Vec3d d{sp * circle[i].first, sp * circle[i].second, cp};
      ids[static_cast<size_t>(j) * n + i] = sink.AddVertex(c + d * rw, d * sign);
    }
  }
  for (int j = 0; j < bands; ++j) {
    for (int i = 0; i < n; ++i) {
      const int i1 = (i + 1) % n;
      const uint32_t p00 = ids[j * n + i], p01 = ids[(j + 1) * n + i];
      const uint32_t p11 = ids[(j + 1) * n + i1], p10 = ids[j * n + i1];
      // (θ, φ) -> (θ, φ+) -> (θ+, φ+) faces outwards; the pole rows collapse to triangles.
      if (j != bands - 1) Tri(sink, sign, p00, p01, p11);
      if (j != 0) Tri(sink, sign, p00, p11, p10);
    }
  }
}

void TessellateCone(const Vec3d& p1, double ra, const Vec3d& p2, double rb, double sign,
                    const UnitCircle& circle, MeshSink& sink) {
  const int n = circle.segments();
  const Vec3d axis = p2 - p1;
  const double h = Length(axis);
  const Vec3d ax = axis / h;
  Vec3d u, w;
  OrthonormalBasis(ax, &u, &w);
  // Surface normal at angle θ: h·ρ(θ) + (ra − rb)·axis, normalised (perpendicular to the
  // slant line). Apex vertices get the normal of their segment's middle.
  auto normal_at = [&](double c, double s) {
    return SafeNormalize((u * c + w * s) * h + ax * (ra - rb)) * sign;
  };
  const double half = kPiD / n;
  std::vector<uint32_t> bottom(n), top(n);
  for (int i = 0; i < n; ++i) {
    const auto [c, s] = circle[i];
    const Vec3d rho = u * c + w * s;
    const double ab = 2.0 * kPiD * i / n + half;  // bottom apex: segment (i, i+1)
    const double at = 2.0 * kPiD * i / n - half;  // top apex: segment (i-1, i)
    bottom[i] =
        sink.AddVertex(p1 + rho * ra, ra > 0.0 ? normal_at(c, s) : normal_at(std::cos(ab), std::sin(ab)));
    top[i] =
        sink.AddVertex(p2 + rho * rb, rb > 0.0 ? normal_at(c, s) : normal_at(std::cos(at), std::sin(at)));
  }
  for (int i = 0; i < n; ++i) {
    const int i1 = (i + 1) % n;
    // (b_i, b_i+1, t_i+1) and (b_i, t_i+1, t_i) face outwards for u × w = axis.
    if (ra > 0.0) Tri(sink, sign, bottom[i], bottom[i1], top[i1]);
    if (rb > 0.0) Tri(sink, sign, bottom[i], top[i1], top[i]);
  }
}

void TessellateRing(const Vec3d& c, const Vec3d& nz, double ri, double ro, const UnitCircle& circle,
                    MeshSink& sink) {
  const int n = circle.segments();
  Vec3d u, w;
  OrthonormalBasis(nz, &u, &w);
  std::vector<uint32_t> inner(n), outer(n);
  const uint32_t centre = ri > 0.0 ? kNone : sink.AddVertex(c, nz);
  for (int i = 0; i < n; ++i) {
    const Vec3d rho = u * circle[i].first + w * circle[i].second;
    outer[i] = sink.AddVertex(c + rho * ro, nz);
    inner[i] = ri > 0.0 ? sink.AddVertex(c + rho * ri, nz) : centre;
  }
  for (int i = 0; i < n; ++i) {
    const int i1 = (i + 1) % n;
    sink.AddTriangle(inner[i], outer[i], outer[i1]);  // ρ × τ = u × w = normal
    if (ri > 0.0) sink.AddTriangle(inner[i], outer[i1], inner[i1]);
  }
}

void TessellateTorus(const Vec3d& c, const Vec3d& nz, double tube, double sweep, double sign,
                     const UnitCircle& circle, MeshSink& sink) {
  const int n = circle.segments();
  Vec3d u, w;
  OrthonormalBasis(nz, &u, &w);
  std::vector<uint32_t> ids(static_cast<size_t>(n) * n);
  for (int i = 0; i < n; ++i) {
    const Vec3d rho = u * circle[i].first + w * circle[i].second;
    for (int j = 0; j < n; ++j) {
      const Vec3d d = rho * circle[j].first + nz * circle[j].second;
      ids[static_cast<size_t>(i) * n + j] = sink.AddVertex(c + rho * sweep + d * tube, d * sign);
    }
  }
  for (int i = 0; i < n; ++i) {
    const int i1 = (i + 1) % n;
    for (int j = 0; j < n; ++j) {
      const int j1 = (j + 1) % n;
      const uint32_t p00 = ids[i * n + j], p10 = ids[i1 * n + j];
      const uint32_t p11 = ids[i1 * n + j1], p01 = ids[i * n + j1];
      Tri(sink, sign, p00, p10, p11);  // ∂θ × ∂φ points away from the tube's core
      Tri(sink, sign, p00, p11, p01);
    }
  }
}

}  // namespace pf::geometry
