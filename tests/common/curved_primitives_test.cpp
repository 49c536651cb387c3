// Curved-primitive tessellation (common/scene/curved_primitives.h): vertices lie on the exact
// surface with its normal, triangles face the way `sign` says, and areas and enclosed volumes
// match the inscribed polyhedra computed in closed form (or the smooth shape within the
// documented tessellation error, mgf_loader.h: sphere, N = 24: -1.4 %).

#include "common/scene/curved_primitives.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <vector>

namespace pf::geometry {
namespace {

constexpr double kPiD = std::numbers::pi;

struct Mesh final : MeshSink {
  std::vector<Vec3d> p, n;
  std::vector<std::array<uint32_t, 3>> tris;
  uint32_t AddVertex(const Vec3d& pos, const Vec3d& normal) override {
    EXPECT_TRUE(tris.empty()) << "vertices must come before triangles";
    p.push_back(pos);
    n.push_back(normal);
    return static_cast<uint32_t>(p.size() - 1);
  }
  void AddTriangle(uint32_t a, uint32_t b, uint32_t c) override {
    EXPECT_LT(std::max({a, b, c}), p.size());
    tris.push_back({a, b, c});
  }
  Vec3d AreaVector(const std::array<uint32_t, 3>& t) const {
    return Cross(p[t[1]] - p[t[0]], p[t[2]] - p[t[0]]) * 0.5;
  }
  double Area() const {
    double a = 0;
    for (const auto& t : tris) a += Length(AreaVector(t));
    return a;
  }
  // Signed volume enclosed (divergence theorem), positive for outward-facing closed meshes.
  double Volume() const {
    double v = 0;
    for (const auto& t : tris) v += Dot(p[t[0]], Cross(p[t[1]], p[t[2]])) / 6.0;
    return v;
  }
  // Every non-degenerate triangle faces the same way as its corners' normals.
  void ExpectFacesAgreeWithNormals() const {
    for (const auto& t : tris) {
      const Vec3d a = AreaVector(t);
      if (Length(a) < 1e-12) continue;
      for (uint32_t v : t) EXPECT_GT(Dot(a, n[v]), 0.0);
    }
  }
};

TEST(CurvedPrimitives, SphereVerticesOnTheSurfaceAndDocumentedAreaError) {
  const Vec3d c{1, -2, 3};
  const UnitCircle circle(24);
  for (const double sign : {1.0, -1.0}) {
    Mesh m;
    TessellateSphere(c, 2.0, sign, circle, m);
    const int bands = SphereBands(24);
    EXPECT_EQ(bands, 12);
    EXPECT_EQ(m.tris.size(), static_cast<size_t>(2 * 24 * bands - 2 * 24));
    for (size_t i = 0; i < m.p.size(); ++i) {
      EXPECT_NEAR(Length(m.p[i] - c), 2.0, 1e-12);
      EXPECT_NEAR(Length(m.n[i] - (m.p[i] - c) * (sign / 2.0)), 0.0, 1e-12);
    }
    m.ExpectFacesAgreeWithNormals();
    // The documented -1.4 % area of N = 24 (mgf_loader.h), and the enclosed volume's sign.
    const double exact_area = 4 * kPiD * 4.0;
    EXPECT_NEAR(m.Area() / exact_area - 1.0, -0.014, 0.001);
    const double exact_volume = 4.0 / 3.0 * kPiD * 8.0;
    EXPECT_NEAR(m.Volume() / exact_volume, sign * 0.97, 0.02);
  }
  // The smallest tessellation still has two bands.
  EXPECT_EQ(SphereBands(3), 2);
}

TEST(CurvedPrimitives, CylinderAndConeAreasMatchTheInscribedPrisms) {
  const int n = 12;
  const UnitCircle circle(n);
  const Vec3d p1{0, 0, 0}, p2{1, 2, 2};  // height 3 along a skew axis
  {
    Mesh m;
    TessellateCone(p1, 0.5, p2, 0.5, 1.0, circle, m);
    ASSERT_EQ(m.tris.size(), static_cast<size_t>(2 * n));
    // n planar quads of width 2 r sin(π/n) and height h.
    EXPECT_NEAR(m.Area(), n * 2 * 0.5 * std::sin(kPiD / n) * 3.0, 1e-12);
    const Vec3d axis = Normalize(p2 - p1);
    for (const Vec3d& normal : m.n) EXPECT_NEAR(Dot(normal, axis), 0.0, 1e-12);
    m.ExpectFacesAgreeWithNormals();
  }
  {
    // A cone with its apex at p2: n triangles of base 2 r sin(π/n) and slant height
    // sqrt(h² + (r cos(π/n))²); normals tilt towards the apex side.
    Mesh m;
    TessellateCone(p1, 1.0, p2, 0.0, 1.0, circle, m);
    ASSERT_EQ(m.tris.size(), static_cast<size_t>(n));
    const double chord = 2 * std::sin(kPiD / n), slant = std::hypot(3.0, std::cos(kPiD / n));
    EXPECT_NEAR(m.Area(), n * 0.5 * chord * slant, 1e-12);
    m.ExpectFacesAgreeWithNormals();
    // Inward-facing (negative radii): every triangle flips.
    Mesh in;
    TessellateCone(p1, 1.0, p2, 0.0, -1.0, circle, in);
    in.ExpectFacesAgreeWithNormals();
    ASSERT_EQ(in.tris.size(), m.tris.size());
    EXPECT_NEAR(Length(in.AreaVector(in.tris[0]) + m.AreaVector(m.tris[0])), 0.0, 1e-12);
  }
}

TEST(CurvedPrimitives, RingsAreFlatAnnuliFacingTheirNormal) {
  const int n = 16;
  const UnitCircle circle(n);
  const Vec3d normal = Normalize(Vec3d{1, 1, 0});
  for (const double ri : {0.0, 0.5}) {
    Mesh m;
    TessellateRing({0, 0, 1}, normal, ri, 2.0, circle, m);
    EXPECT_EQ(m.tris.size(), static_cast<size_t>(ri > 0 ? 2 * n : n));
    // The inscribed regular n-gons: n/2 sin(2π/n) (ro² − ri²).
    EXPECT_NEAR(m.Area(), n / 2.0 * std::sin(2 * kPiD / n) * (4.0 - ri * ri), 1e-12);
    for (const auto& t : m.tris) {
      const Vec3d a = m.AreaVector(t);
      EXPECT_NEAR(Length(Cross(a, normal)), 0.0, 1e-12);
      EXPECT_GT(Dot(a, normal), 0.0);
    }
    for (const Vec3d& p : m.p) EXPECT_NEAR(Dot(p - Vec3d{0, 0, 1}, normal), 0.0, 1e-12);
  }
}

TEST(CurvedPrimitives, TorusIsClosedAndFacesOutwardsOrInwards) {
  const int n = 24;
  const UnitCircle circle(n);
  const Vec3d c{0, 1, 0}, axis{0, 0, 1};
  const double tube = 0.5, sweep = 2.0;
  for (const double sign : {1.0, -1.0}) {
    Mesh m;
    TessellateTorus(c, axis, tube, sweep, sign, circle, m);
    EXPECT_EQ(m.p.size(), static_cast<size_t>(n * n));
    EXPECT_EQ(m.tris.size(), static_cast<size_t>(2 * n * n));
    for (const Vec3d& p : m.p) {
      // Distance from the sweep circle (in the plane z = 0 about c) is the tube radius.
      const Vec3d d = p - c;
      EXPECT_NEAR(std::hypot(std::hypot(d.x, d.y) - sweep, d.z), tube, 1e-12);
    }
    m.ExpectFacesAgreeWithNormals();
    // Volume 2π² R r², less the tessellation's shrinkage (two circles of 24 segments, ~1 % each).
    const double exact = 2 * kPiD * kPiD * sweep * tube * tube;
    EXPECT_NEAR(m.Volume() / exact, sign * 0.98, 0.015);
  }
}

TEST(CurvedPrimitives, UnitCircleClosesExactly) {
  const UnitCircle circle(7);
  EXPECT_EQ(circle.segments(), 7);
  EXPECT_EQ(circle[7], circle[0]);
  EXPECT_EQ(circle[0], (std::pair<double, double>{1.0, 0.0}));
  for (int i = 0; i < 7; ++i) {
    EXPECT_NEAR(circle[i].first, std::cos(2 * kPiD * i / 7), 1e-15);
    EXPECT_NEAR(circle[i].second, std::sin(2 * kPiD * i / 7), 1e-15);
  }
}

}  // namespace
}  // namespace pf::geometry
