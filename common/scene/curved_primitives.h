#pragma once
// Tessellation of curved primitives into triangles with smooth per-vertex normals: sphere,
// truncated cone (cylinder), ring and torus, as MGF defines them (mgfdoc.tr §3 sph, cyl, cone,
// ring, torus). The rule, N equal arcs per full circle and every vertex on the exact surface, is
// documented in mgf_loader.h. Inputs are in world space and already validated (radii positive
// and usable, distinct cone end points, unit normals); `sign` > 0 makes triangles and normals
// face outwards, `sign` < 0 inwards (§3: negative radii).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "common/core/math.h"

namespace pf::geometry {

// Receives the vertices and triangles of a tessellated primitive, in order: all vertices of a
// primitive come before its first triangle. Triangles index the ids AddVertex returned.
class MeshSink {
 public:
  virtual uint32_t AddVertex(const Vec3d& p, const Vec3d& n) = 0;
  virtual void AddTriangle(uint32_t a, uint32_t b, uint32_t c) = 0;

 protected:
  ~MeshSink() = default;
};

// cos, sin of the N segment angles 2πi/N, i = 0..N; entry N repeats entry 0 exactly, so that
// the circle closes exactly.
class UnitCircle {
 public:
  explicit UnitCircle(int segments);
  int segments() const { return static_cast<int>(cos_sin_.size()) - 1; }
  const std::pair<double, double>& operator[](size_t i) const { return cos_sin_[i]; }

 private:
  std::vector<std::pair<double, double>> cos_sin_;
};

// Latitude bands between the poles of a sphere cut into `segments` arcs around: N/2, at least 2.
inline int SphereBands(int segments) {
  return std::max(2, segments / 2);
}

// Sphere of radius `radius` about `centre` (§3 sph): 2·N·bands − 2·N triangles.
void TessellateSphere(const Vec3d& centre, double radius, double sign, const UnitCircle& circle,
                      MeshSink& sink);

// Open-ended truncated cone from p1 (radius ra) to p2 (radius rb) (§3 cyl, cone); a zero radius
// is an apex: one vertex per segment with the normal at the segment's middle. N triangles per
// non-zero radius.
void TessellateCone(const Vec3d& p1, double ra, const Vec3d& p2, double rb, double sign,
                    const UnitCircle& circle, MeshSink& sink);

// Flat annulus (a disc if r_inner is 0) about `centre`, facing along the unit `normal` (§3 ring).
void TessellateRing(const Vec3d& centre, const Vec3d& normal, double r_inner, double r_outer,
                    const UnitCircle& circle, MeshSink& sink);

// Torus about `centre` with the unit `normal` as its axis: a tube of radius `tube` swept around a
// circle of radius `sweep` (§3 torus): 2·N² triangles.
void TessellateTorus(const Vec3d& centre, const Vec3d& normal, double tube, double sweep, double sign,
                     const UnitCircle& circle, MeshSink& sink);

}  // namespace pf::geometry
