// Polygon triangulation (common/scene/polygon_triangulation.h): ear clipping in the Newell plane
// and hole bridging. The triangles of a simple polygon must tile it exactly: their areas, all
// with the polygon's orientation, sum to the shoelace area, and no triangle covers a hole.

#include "common/scene/polygon_triangulation.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace pf::geometry {
namespace {

using Triangles = std::vector<std::array<uint32_t, 3>>;

// A tilted plane, so that the triangulator has to find it (not an axis-aligned projection).
struct Plane {
  Vec3d origin{0.3, -1.2, 2.0};
  Vec3d u = Normalize(Vec3d{1.0, 0.4, -0.2});
  Vec3d w = Normalize(Cross(Vec3d{0.1, 0.3, 1.0}, Normalize(Vec3d{1.0, 0.4, -0.2})));
  Vec3d normal = Cross(u, w);
  Vec3d At(double x, double y) const { return origin + u * x + w * y; }
};

std::vector<Vec3d> InPlane(const Plane& plane, const std::vector<std::array<double, 2>>& xy) {
  std::vector<Vec3d> out;
  for (const auto& [x, y] : xy) out.push_back(plane.At(x, y));
  return out;
}

// Shoelace area of a 2D contour (positive for counter-clockwise).
double ShoelaceArea(const std::vector<std::array<double, 2>>& xy) {
  double s = 0;
  for (size_t i = 0; i < xy.size(); ++i) {
    const auto& a = xy[i];
    const auto& b = xy[(i + 1) % xy.size()];
    s += a[0] * b[1] - b[0] * a[1];
  }
  return 0.5 * s;
}

// Area of triangle t measured along `normal` (negative if it faces the other way).
double SignedArea(const std::vector<Vec3d>& pts, const std::array<uint32_t, 3>& t, const Vec3d& normal) {
  return 0.5 * Dot(Cross(pts[t[1]] - pts[t[0]], pts[t[2]] - pts[t[0]]), normal);
}

bool InsideConvex2d(const std::vector<std::array<double, 2>>& ccw, double x, double y) {
  for (size_t i = 0; i < ccw.size(); ++i) {
    const auto& a = ccw[i];
    const auto& b = ccw[(i + 1) % ccw.size()];
    if ((b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) <= 0.0) return false;
  }
  return true;
}

TEST(PolygonTriangulation, ConcavePolygonIsTiledExactly) {
  const Plane plane;
  // A comb: three teeth, so that most vertices are reflex or have a blocked ear.
  const std::vector<std::array<double, 2>> comb = {{0, 0}, {7, 0}, {7, 4}, {6, 4}, {6, 1}, {4, 1},
                                                   {4, 4}, {3, 4}, {3, 1}, {1, 1}, {1, 4}, {0, 4}};
  const std::vector<Vec3d> pts = InPlane(plane, comb);
  Triangles tris;
  bool approximate = true;
  ASSERT_TRUE(TriangulatePolygon(pts, &tris, &approximate));
  EXPECT_FALSE(approximate);
  // At most n - 2 triangles: vertices that become collinear while clipping are dropped.
  EXPECT_LE(tris.size(), comb.size() - 2);
  double area = 0;
  for (const auto& t : tris) {
    const double a = SignedArea(pts, t, plane.normal);
    EXPECT_GT(a, 1e-9) << "triangle against the polygon's orientation or degenerate";
    area += a;
  }
  EXPECT_NEAR(area, ShoelaceArea(comb), 1e-9);  // 7·1 + 3 teeth of 1·3 = 16
  EXPECT_NEAR(area, 16.0, 1e-9);

  // Clockwise input keeps its orientation: every triangle faces the other way.
  std::vector<Vec3d> reversed(pts.rbegin(), pts.rend());
  ASSERT_TRUE(TriangulatePolygon(reversed, &tris, &approximate));
  double reversed_area = 0;
  for (const auto& t : tris) reversed_area += SignedArea(reversed, t, plane.normal);
  EXPECT_NEAR(reversed_area, -16.0, 1e-9);
}

TEST(PolygonTriangulation, DuplicateAndCollinearVerticesCostNoArea) {
  const Plane plane;
  const std::vector<std::array<double, 2>> square = {{0, 0}, {1, 0}, {2, 0}, {2, 0}, {2, 2},
                                                     {1, 2}, {0, 2}, {0, 1}, {0, 0}};
  const std::vector<Vec3d> pts = InPlane(plane, square);
  Triangles tris;
  bool approximate = true;
  ASSERT_TRUE(TriangulatePolygon(pts, &tris, &approximate));
  EXPECT_FALSE(approximate);
  double area = 0;
  for (const auto& t : tris) area += SignedArea(pts, t, plane.normal);
  EXPECT_NEAR(area, 4.0, 1e-12);
}

TEST(PolygonTriangulation, DegenerateAndSelfIntersectingInput) {
  const Plane plane;
  Triangles tris;
  bool approximate = false;
  // Fewer than three distinct points, and collinear points: no area, nothing emitted.
  EXPECT_FALSE(TriangulatePolygon(InPlane(plane, {{0, 0}, {1, 1}, {1, 1}, {0, 0}}), &tris, &approximate));
  EXPECT_FALSE(TriangulatePolygon(InPlane(plane, {{0, 0}, {1, 1}, {2, 2}, {3, 3}}), &tris, &approximate));
  EXPECT_TRUE(tris.empty());
  // A figure eight whose loops are not equal has area, but no proper ear decomposition.
  const std::vector<Vec3d> eight = InPlane(plane, {{0, 0}, {4, 2}, {4, 0}, {0, 3}});
  EXPECT_TRUE(TriangulatePolygon(eight, &tris, &approximate));
  EXPECT_TRUE(approximate);
}

TEST(PolygonTriangulation, HolesAreBridgedAndLeftUncovered) {
  const Plane plane;
  const std::vector<std::array<double, 2>> outer = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  // One hole counter-clockwise, one clockwise (BridgeHoles accepts either), and one outside.
  const std::vector<std::array<double, 2>> square_hole = {{2, 2}, {4, 2}, {4, 4}, {2, 4}};
  const std::vector<std::array<double, 2>> triangle_hole_cw = {{6, 6}, {6, 8}, {8, 6}};
  const std::vector<std::array<double, 2>> outside = {{20, 20}, {21, 20}, {21, 21}};
  const std::vector<std::vector<Vec3d>> contours = {InPlane(plane, outer), InPlane(plane, square_hole),
                                                    InPlane(plane, triangle_hole_cw),
                                                    InPlane(plane, outside)};
  std::vector<ContourVertex> merged;
  size_t ignored = 99;
  ASSERT_TRUE(BridgeHoles(contours, &merged, &ignored));
  EXPECT_EQ(ignored, 1u);
  // Every vertex of the outer contour and of the two inside holes appears, plus two seam
  // copies per bridged hole.
  EXPECT_EQ(merged.size(), 4u + (4 + 2) + (3 + 2));

  std::vector<Vec3d> pts;
  for (const ContourVertex& v : merged) pts.push_back(contours[v.contour][v.index]);
  Triangles tris;
  bool approximate = true;
  ASSERT_TRUE(TriangulatePolygon(pts, &tris, &approximate));
  EXPECT_FALSE(approximate);
  double area = 0;
  const std::vector<std::array<double, 2>> triangle_hole_ccw = {{6, 6}, {8, 6}, {6, 8}};
  for (const auto& t : tris) {
    const double a = SignedArea(pts, t, plane.normal);
    EXPECT_GT(a, 1e-9);
    area += a;
    const Vec3d centroid = (pts[t[0]] + pts[t[1]] + pts[t[2]]) / 3.0;
    const double x = Dot(centroid - plane.origin, plane.u), y = Dot(centroid - plane.origin, plane.w);
    EXPECT_FALSE(InsideConvex2d(square_hole, x, y)) << "a triangle covers the square hole";
    EXPECT_FALSE(InsideConvex2d(triangle_hole_ccw, x, y)) << "a triangle covers the triangular hole";
  }
  EXPECT_NEAR(area, 100.0 - 4.0 - 2.0, 1e-9);

  // An outer contour without area cannot take holes.
  const std::vector<std::vector<Vec3d>> flat = {InPlane(plane, {{0, 0}, {1, 0}, {2, 0}}),
                                                InPlane(plane, square_hole)};
  EXPECT_FALSE(BridgeHoles(flat, &merged, &ignored));
}

TEST(PolygonTriangulation, OrthonormalBasisAndSafeNormalize) {
  for (const Vec3d n : {Vec3d{0, 0, 1}, Vec3d{0, 0, -1}, Normalize(Vec3d{1, 2, 3}),
                        Normalize(Vec3d{-3, 0.5, -0.1}), Vec3d{1, 0, 0}}) {
    Vec3d u, w;
    OrthonormalBasis(n, &u, &w);
    EXPECT_NEAR(Length(u), 1.0, 1e-12);
    EXPECT_NEAR(Length(w), 1.0, 1e-12);
    EXPECT_NEAR(Dot(u, w), 0.0, 1e-12);
    EXPECT_NEAR(Length(Cross(u, w) - n), 0.0, 1e-12);  // u × w = n
  }
  // Components whose squares would overflow or underflow still normalise.
  const Vec3d huge = SafeNormalize({3e300, 4e300, 0});
  EXPECT_NEAR(huge.x, 0.6, 1e-15);
  EXPECT_NEAR(huge.y, 0.8, 1e-15);
  const Vec3d tiny = SafeNormalize({0, -3e-300, 4e-300});
  EXPECT_NEAR(tiny.y, -0.6, 1e-15);
  EXPECT_NEAR(tiny.z, 0.8, 1e-15);
  EXPECT_EQ(SafeNormalize({0, 0, 0}), (Vec3d{}));
}

}  // namespace
}  // namespace pf::geometry
