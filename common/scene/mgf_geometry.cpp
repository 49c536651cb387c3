// The MGF entities that emit triangles (mgfdoc.tr §3 f, fh, sph, cyl, cone, prism, ring, torus),
// by the tessellation and orientation rules of mgf_loader.h: polygons through
// polygon_triangulation.h, curved primitives through curved_primitives.h, each source primitive
// one light when its material emits.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common/scene/curved_primitives.h"
#include "common/scene/mgf_reader.h"
#include "common/scene/polygon_triangulation.h"

namespace pf::mgf {
namespace {

// Beyond this magnitude (after transformation) coordinates are rejected: products of two such
// numbers stay far from overflow in double, and the value still fits a float.
constexpr double kMaxCoordinate = 1e18;
// The spec limits an entity to 4096 characters, i.e. about 2000 vertices per face; far larger
// polygons are refused rather than ear-clipped in quadratic time.
constexpr size_t kMaxPolygonVertices = 16384;

}  // namespace

void MgfReader::EmitGeometry(Kind kind, const Args& a) {
  using Emitter = void (MgfReader::*)(const Args&);
  static constexpr std::pair<Kind, Emitter> kEmitters[] = {
      {Kind::kFace, &MgfReader::Face},     {Kind::kFaceHoles, &MgfReader::FaceWithHoles},
      {Kind::kSphere, &MgfReader::Sphere}, {Kind::kCylinder, &MgfReader::Cylinder},
      {Kind::kCone, &MgfReader::Cone},     {Kind::kPrism, &MgfReader::Prism},
      {Kind::kRing, &MgfReader::Ring},     {Kind::kTorus, &MgfReader::Torus},
  };
  for (const auto& [k, emit] : kEmitters)
    if (k == kind) return (this->*emit)(a);
}

void MgfReader::BeginPrimitive(size_t expected_triangles) {
  if (scene_.triangles.size() + expected_triangles > options_.budget.max_triangles) {
    Fail("more than " + std::to_string(options_.budget.max_triangles) +
         " triangles (SceneBudget::max_triangles)");
  }
  prim_material_ = MaterialIndex();
  prim_emissive_ = scene_.materials[prim_material_].IsEmissive();
  prim_light_ = kNoLight;
}

uint32_t MgfReader::AddVertex(const Vec3d& p, const Vec3d& n) {
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(p[k]) <= kMaxCoordinate)) {
      Fail("coordinates out of range after transformation (|x| > 1e18)");
    }
  }
  if (world_positions_.size() >= std::min<uint64_t>(options_.budget.max_vertices, 0xfffffff0u)) {
    Fail("more than " + std::to_string(options_.budget.max_vertices) +
         " vertices (SceneBudget::max_vertices)");
  }
  world_positions_.push_back(p);  // in double until the scene's frame is known (Finish)
  scene_.normals.push_back(Vec3(n));
  any_normal_ = any_normal_ || !(n == Vec3d{});
  return static_cast<uint32_t>(world_positions_.size() - 1);
}

void MgfReader::AddTriangle(uint32_t a, uint32_t b, uint32_t c) {
  if (scene_.triangles.size() >= options_.budget.max_triangles) {
    Fail("more than " + std::to_string(options_.budget.max_triangles) +
         " triangles (SceneBudget::max_triangles)");
  }
  if (prim_emissive_ && prim_light_ == kNoLight) prim_light_ = scene_.num_lights++;
  scene_.triangles.push_back({a, b, c});
  scene_.triangle_material.push_back(prim_material_);
  scene_.triangle_light.push_back(prim_emissive_ ? prim_light_ : kNoLight);
}

bool MgfReader::EmitPolygon(std::span<const PolyVertex> poly, bool use_normals, std::string_view what) {
  poly_points_.resize(poly.size());
  for (size_t i = 0; i < poly.size(); ++i) poly_points_[i] = poly[i].p;
  bool approximate = false;
  if (!geometry::TriangulatePolygon(poly_points_, &poly_tris_, &approximate)) return false;
  if (approximate) {
    Warn(std::string(what) + ": self-intersecting polygon, triangulated approximately");
  }
  remap_.assign(poly.size(), kNone);
  auto vertex = [&](uint32_t i) {
    if (remap_[i] == kNone) remap_[i] = AddVertex(poly[i].p, use_normals ? poly[i].n : Vec3d{});
    return remap_[i];
  };
  for (const auto& t : poly_tris_) {
    const uint32_t a = vertex(t[0]), b = vertex(t[1]), c = vertex(t[2]);
    AddTriangle(a, b, c);
  }
  return true;
}

void MgfReader::WorldPolygon(const Args& a, size_t first, size_t end, std::vector<PolyVertex>* out,
                             bool* all_normals) const {
  if (end - first > kMaxPolygonVertices) {
    Fail(std::string(a.keyword()) + ": more than " + std::to_string(kMaxPolygonVertices) +
         " vertices in one polygon");
  }
  const Affine& xf = World();
  out->clear();
  *all_normals = true;
  for (size_t i = first; i < end; ++i) {
    const VertexCtx& v = NamedVertex(a[i]);
    const bool has_n = !(v.n == Vec3d{});
    *all_normals = *all_normals && has_n;
    out->push_back({xf.Point(v.p), has_n ? geometry::SafeNormalize(xf.Vector(v.n)) : Vec3d{}});
  }
  if (xf.Mirrors()) std::reverse(out->begin(), out->end());
}

void MgfReader::Face(const Args& a) {
  if (a.size() < 4) Fail("f: expected at least 3 vertex names, got " + std::to_string(a.size() - 1));
  bool all_normals;
  WorldPolygon(a, 1, a.size(), &poly_, &all_normals);
  BeginPrimitive(a.size());
  if (!EmitPolygon(poly_, all_normals, "f")) Warn("f: degenerate face (no area) skipped");
}

void MgfReader::FaceWithHoles(const Args& a) {
  std::vector<std::pair<size_t, size_t>> contours;  // [first, end) word ranges
  size_t start = 1;
  for (size_t i = 1; i <= a.size(); ++i) {
    if (i == a.size() || a[i] == "-") {
      if (i - start < 3) Fail("fh: every contour needs at least 3 vertices");
      contours.emplace_back(start, i);
      start = i + 1;
    }
  }
  std::vector<std::vector<PolyVertex>> rings(contours.size());
  bool all_normals = true;
  for (size_t k = 0; k < contours.size(); ++k) {
    bool n;
    WorldPolygon(a, contours[k].first, contours[k].second, &rings[k], &n);
    all_normals = all_normals && n;
  }
  BeginPrimitive(a.size() * 3);
  std::vector<std::vector<Vec3d>> contour_points(rings.size());
  for (size_t k = 0; k < rings.size(); ++k) {
    for (const PolyVertex& v : rings[k]) contour_points[k].push_back(v.p);
  }
  std::vector<geometry::ContourVertex> bridged;
  size_t ignored_holes = 0;
  if (!geometry::BridgeHoles(contour_points, &bridged, &ignored_holes)) {
    Warn("fh: degenerate outer contour (no area) skipped");
    return;
  }
  for (size_t k = 0; k < ignored_holes; ++k) {
    Warn("fh: a hole lies outside the outer contour; hole ignored");
  }
  std::vector<PolyVertex> merged;
  merged.reserve(bridged.size());
  for (const geometry::ContourVertex& v : bridged) merged.push_back(rings[v.contour][v.index]);
  if (!EmitPolygon(merged, all_normals, "fh")) Warn("fh: degenerate face (no area) skipped");
}

Vec3d MgfReader::CheckedPoint(const Vec3d& p) const {
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(p[k]) <= kMaxCoordinate)) {
      Fail("coordinates out of range after transformation (|x| > 1e18)");
    }
  }
  return p;
}

bool MgfReader::UsableRadius(double r) const {
  if (!(r <= kMaxCoordinate)) Fail("radius out of range after transformation (> 1e18)");
  return r > 1e-300;
}

void MgfReader::Sphere(const Args& a) {
  ExpectCount(a, 2, 2, "2 arguments (vc radius)");
  const VertexCtx& vc = NamedVertex(a[1]);
  const double r = Number(a, 2);
  if (r == 0.0) Fail("sph: radius must not be zero");
  const Affine& xf = World();
  const Vec3d c = CheckedPoint(xf.Point(vc.p));
  const double scale = xf.Scale();
  const double rw = std::abs(r) * scale;
  const double sign = r > 0.0 ? 1.0 : -1.0;  // negative radius: inward normals (§3 sph)
  const int n = options_.curve_segments;
  const int bands = geometry::SphereBands(n);
  BeginPrimitive(static_cast<size_t>(2) * n * bands);
  if (!UsableRadius(rw)) {
    Warn("sph: radius vanishes after transformation; skipped");
    return;
  }
  geometry::TessellateSphere(c, rw, sign, circle_, *this);
}

void MgfReader::Cylinder(const Args& a) {
  ExpectCount(a, 3, 3, "3 arguments (v1 radius v2)");
  const double r = Number(a, 2);
  if (r == 0.0) Fail("cyl: radius must not be zero");
  TruncatedCone(a, a[1], r, a[3], r);
}

void MgfReader::Cone(const Args& a) {
  ExpectCount(a, 4, 4, "4 arguments (v1 rad1 v2 rad2)");
  const double r1 = Number(a, 2), r2 = Number(a, 4);
  if (r1 == 0.0 && r2 == 0.0) Fail("cone: both radii are zero");
  if ((r1 > 0.0 && r2 < 0.0) || (r1 < 0.0 && r2 > 0.0)) {
    Fail("cone: the radii must not have opposite signs");
  }
  TruncatedCone(a, a[1], r1, a[3], r2);
}

void MgfReader::TruncatedCone(const Args& a, std::string_view n1, double r1, std::string_view n2, double r2) {
  const VertexCtx& v1 = NamedVertex(n1);
  const VertexCtx& v2 = NamedVertex(n2);
  if (v1.p == v2.p) {
    Fail(std::string(a.keyword()) + ": the end points coincide" +
         (a.keyword() == "cone" ? " (use ring)" : ""));
  }
  const Affine& xf = World();
  const Vec3d p1 = CheckedPoint(xf.Point(v1.p)), p2 = CheckedPoint(xf.Point(v2.p));
  const double scale = xf.Scale();
  const double sign = (r1 < 0.0 || r2 < 0.0) ? -1.0 : 1.0;  // negative radii face inwards
  const double ra = std::abs(r1) * scale, rb = std::abs(r2) * scale;
  const int n = options_.curve_segments;
  BeginPrimitive(static_cast<size_t>(2) * n);
  const Vec3d axis = p2 - p1;
  const double h = Length(axis);
  if (!UsableRadius(std::max(ra, rb)) || !(h > 0.0)) {
    Warn(std::string(a.keyword()) + ": degenerate after transformation; skipped");
    return;
  }
  geometry::TessellateCone(p1, ra, p2, rb, sign, circle_, *this);
}

const VertexCtx& MgfReader::OrientedCentre(const Args& a) const {
  const VertexCtx& vc = NamedVertex(a[1]);
  if (vc.n == Vec3d{}) {
    Fail(std::string(a.keyword()) + ": centre vertex " + Quote(a[1]) + " has no normal");
  }
  return vc;
}

void MgfReader::Ring(const Args& a) {
  ExpectCount(a, 3, 3, "3 arguments (vc rmin rmax)");
  const VertexCtx& vc = OrientedCentre(a);
  const double rmin = Number(a, 2), rmax = Number(a, 3);
  if (rmin < 0.0) Fail("ring: inner radius must not be negative");
  if (!(rmax > rmin)) Fail("ring: outer radius must be greater than the inner radius");
  const Affine& xf = World();
  const Vec3d c = CheckedPoint(xf.Point(vc.p));
  const Vec3d nz = geometry::SafeNormalize(xf.Vector(vc.n));
  const double scale = xf.Scale();
  const double ri = rmin * scale, ro = rmax * scale;
  const int n = options_.curve_segments;
  BeginPrimitive(static_cast<size_t>(2) * n);
  if (nz == Vec3d{} || !UsableRadius(ro)) {
    Warn("ring: degenerate after transformation; skipped");
    return;
  }
  geometry::TessellateRing(c, nz, ri, ro, circle_, *this);
}

void MgfReader::Torus(const Args& a) {
  ExpectCount(a, 3, 3, "3 arguments (vc rmin rmax)");
  const VertexCtx& vc = OrientedCentre(a);
  const double rmin = Number(a, 2), rmax = Number(a, 3);
  if (rmax == 0.0) Fail("torus: outer radius must not be zero");
  if (rmax > 0.0 && rmin < 0.0) Fail("torus: inner radius must not be negative");
  if (rmax < 0.0 && rmin > 0.0) Fail("torus: inner radius must not be positive for an inward torus");
  if (!(std::abs(rmax) > std::abs(rmin))) {
    Fail("torus: |outer radius| must be greater than |inner radius|");
  }
  const double sign = rmax > 0.0 ? 1.0 : -1.0;
  const Affine& xf = World();
  const Vec3d c = CheckedPoint(xf.Point(vc.p));
  const Vec3d nz = geometry::SafeNormalize(xf.Vector(vc.n));
  const double scale = xf.Scale();
  const double tube = (std::abs(rmax) - std::abs(rmin)) * 0.5 * scale;
  const double sweep = (std::abs(rmax) + std::abs(rmin)) * 0.5 * scale;
  const int n = options_.curve_segments;
  BeginPrimitive(static_cast<size_t>(2) * n * n);
  if (nz == Vec3d{} || !UsableRadius(tube) || !UsableRadius(sweep)) {
    Warn("torus: degenerate after transformation; skipped");
    return;
  }
  geometry::TessellateTorus(c, nz, tube, sweep, sign, circle_, *this);
}

void MgfReader::Prism(const Args& a) {
  if (a.size() < 5) Fail("prism: expected at least 3 vertex names and a length");
  const double length = Number(a, a.size() - 1);
  if (length == 0.0) Fail("prism: length must not be zero");
  bool all_normals;
  WorldPolygon(a, 1, a.size() - 1, &poly_, &all_normals);
  const size_t n = poly_.size();
  BeginPrimitive(4 * n);
  Vec3d area2;
  for (size_t i = 0; i < n; ++i) area2 += Cross(poly_[i].p - poly_[0].p, poly_[(i + 1) % n].p - poly_[0].p);
  const Vec3d nz = geometry::SafeNormalize(area2);
  const double scale = World().Scale();
  if (nz == Vec3d{}) {
    Warn("prism: degenerate end face (no area) skipped");
    return;
  }
  const Vec3d d = nz * (-length * scale);
  std::vector<PolyVertex> end_face(poly_.size());
  for (size_t i = 0; i < n; ++i) end_face[i] = {poly_[n - 1 - i].p + d, {}};
  const std::vector<PolyVertex>& base = poly_;
  EmitPolygon(base, false, "prism");
  EmitPolygon(end_face, false, "prism");
  for (size_t i = 0; i < n; ++i) {
    const PolyVertex& p = base[i];
    const PolyVertex& q = base[(i + 1) % n];
    const std::array<PolyVertex, 4> side = {PolyVertex{p.p, p.n}, PolyVertex{p.p + d, p.n},
                                            PolyVertex{q.p + d, q.n}, PolyVertex{q.p, q.n}};
    EmitPolygon(side, all_normals, "prism");
  }
}

}  // namespace pf::mgf
