#pragma once
// Polygon triangulation in 3D: ear clipping in the polygon's best-fit (Newell) plane, and the
// bridging of holes into the outer contour that turns a polygon with holes into one seamed
// polygon. Written for MGF's `f`/`fh` (mgfdoc.tr §3 f: "holes as concave polygons with
// coincident sides"; §3 fh), but nothing here is MGF-specific.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "common/core/math.h"

namespace pf::geometry {

// Orthonormal u, w with u × w = n for unit n (Duff et al. 2017, as Frame in core/math.h).
void OrthonormalBasis(const Vec3d& n, Vec3d* u, Vec3d* w);

// Unit vector along v, or zero if v is zero (robust for huge and tiny components).
Vec3d SafeNormalize(const Vec3d& v);

// Triangulates a planar (or nearly planar) polygon by ear clipping in its best-fit plane.
// Triangles index `pts` and keep the polygon's orientation (right-hand rule). Returns false if
// the polygon is degenerate (fewer than three distinct points, or no area). Sets *approximate if
// no proper ear was found at some point (self-intersecting input): the result then still covers
// the polygon's vertices but may overlap or miss parts of it.
bool TriangulatePolygon(std::span<const Vec3d> pts, std::vector<std::array<uint32_t, 3>>* out,
                        bool* approximate);

// One vertex of one contour of a polygon with holes: contours[contour][index].
struct ContourVertex {
  uint32_t contour;
  uint32_t index;
};

// Merges a polygon with holes into one seamed polygon that TriangulatePolygon handles.
// contours[0] is the outer contour (its orientation is kept), the others are holes (either
// orientation). Connects each hole to the outer contour through a pair of coincident seam edges:
// from the hole's extreme vertex M along +u to the nearest contour edge, then to a visible contour
// vertex P (the classic hole elimination of ear-clipping triangulators). Holes are processed
// from the largest u down, so a later bridge may also land on an earlier hole.
// Returns false if the outer contour has no area. Holes that lie outside the outer contour are
// left out and counted in *ignored_holes.
bool BridgeHoles(std::span<const std::vector<Vec3d>> contours, std::vector<ContourVertex>* merged,
                 size_t* ignored_holes);

}  // namespace pf::geometry
