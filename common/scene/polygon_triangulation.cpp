// Polygon triangulation (polygon_triangulation.h).

#include "common/scene/polygon_triangulation.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <utility>

namespace pf::geometry {
namespace {
constexpr uint32_t kNone = 0xffffffffu;
}  // namespace

void OrthonormalBasis(const Vec3d& n, Vec3d* u, Vec3d* w) {
  const double sign = std::copysign(1.0, n.z);
  const double a = -1.0 / (sign + n.z);
  const double b = n.x * n.y * a;
  *u = {1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x};
  *w = {b, sign + n.y * n.y * a, -n.y};
}

Vec3d SafeNormalize(const Vec3d& v) {
  const double m = std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
  if (!(m > 0.0) || !std::isfinite(m)) return {};
  const Vec3d s = v / m;
  return s / Length(s);
}

bool TriangulatePolygon(std::span<const Vec3d> pts, std::vector<std::array<uint32_t, 3>>* out,
                        bool* approximate) {
  out->clear();
  *approximate = false;
  std::vector<uint32_t> idx;
  idx.reserve(pts.size());
  for (uint32_t i = 0; i < pts.size(); ++i) {
    if (idx.empty() || !(pts[i] == pts[idx.back()])) idx.push_back(i);
  }
  while (idx.size() > 1 && pts[idx.back()] == pts[idx.front()]) idx.pop_back();
  const size_t n = idx.size();
  if (n < 3) return false;

  // Newell's normal: the area vector of the polygon, robust for concave and non-planar input.
  const Vec3d o = pts[idx[0]];
  Vec3d area2;
  Vec3d lo = o, hi = o;
  for (size_t i = 0; i < n; ++i) {
    const Vec3d& p = pts[idx[i]];
    area2 += Cross(p - o, pts[idx[(i + 1) % n]] - o);
    lo = Min(lo, p);
    hi = Max(hi, p);
  }
  const double extent = MaxComponent(hi - lo);
  const double eps = 1e-12 * extent * extent;  // in units of twice an area
  const double len = Length(area2);
  if (!(extent > 0.0) || !(len > eps)) return false;
  if (n == 3) {
    out->push_back({idx[0], idx[1], idx[2]});
    return true;
  }

  // 2D coordinates in the plane; the polygon is counter-clockwise there by construction.
  Vec3d u, w;
  OrthonormalBasis(area2 / len, &u, &w);
  std::vector<double> qx(n), qy(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec3d d = pts[idx[i]] - o;
    qx[i] = Dot(d, u);
    qy[i] = Dot(d, w);
  }
  auto cross = [&](size_t a, size_t b, size_t c) {
    return (qx[b] - qx[a]) * (qy[c] - qy[a]) - (qy[b] - qy[a]) * (qx[c] - qx[a]);
  };
  auto same = [&](size_t a, size_t b) { return qx[a] == qx[b] && qy[a] == qy[b]; };
  std::vector<uint32_t> prev(n), next(n);
  for (size_t i = 0; i < n; ++i) {
    prev[i] = static_cast<uint32_t>((i + n - 1) % n);
    next[i] = static_cast<uint32_t>((i + 1) % n);
  }
  // An ear (a, b, c) may not contain any other remaining vertex, on its boundary included, except
  // vertices coincident with its corners: that exception is what makes MGF seams work, where a
  // hole's bridge vertices appear twice (§3 f).
  auto is_ear = [&](size_t a, size_t b, size_t c) {
    for (size_t r = next[c]; r != a; r = next[r]) {
      if (same(r, a) || same(r, b) || same(r, c)) continue;
      if (cross(a, b, r) >= -eps && cross(b, c, r) >= -eps && cross(c, a, r) >= -eps) {
        return false;
      }
    }
    return true;
  };

  size_t remaining = n;
  size_t cur = 0;
  size_t stall = 0;
  while (remaining > 3) {
    const size_t a = prev[cur], c = next[cur];
    const double cr = cross(a, cur, c);
    bool clip = false, emit = false;
    size_t victim = cur;
    if (std::abs(cr) <= eps) {
      clip = true;  // collinear vertex or zero-width spike: dropping it loses no area
    } else if (cr > 0.0 && (*approximate || is_ear(a, cur, c))) {
      // Once the polygon is known to intersect itself, ears are no longer searched for (that
      // could take cubic time): every convex vertex is clipped.
      clip = emit = true;
    } else if (++stall > remaining) {
      // A full lap without an ear: the polygon intersects itself. Clip some convex vertex
      // anyway (or drop one) so that the loop always terminates.
      *approximate = true;
      clip = true;
      size_t v = cur;
      do {
        if (cross(prev[v], v, next[v]) > eps) {
          victim = v;
          emit = true;
          break;
        }
        v = next[v];
      } while (v != cur);
    }
    if (!clip) {
      cur = c;
      continue;
    }
    const size_t va = prev[victim], vc = next[victim];
    if (emit) out->push_back({idx[va], idx[victim], idx[vc]});
    next[va] = static_cast<uint32_t>(vc);
    prev[vc] = static_cast<uint32_t>(va);
    --remaining;
    stall = 0;
    cur = vc;
  }
  const size_t a = prev[cur], c = next[cur];
  const double cr = cross(a, cur, c);
  if (cr > eps) {
    out->push_back({idx[a], idx[cur], idx[c]});
  } else if (cr < -eps) {
    *approximate = true;
  }
  return !out->empty();
}

bool BridgeHoles(std::span<const std::vector<Vec3d>> contours, std::vector<ContourVertex>* merged,
                 size_t* ignored_holes) {
  *ignored_holes = 0;
  merged->clear();
  const std::vector<Vec3d>& outer = contours[0];
  Vec3d area2;
  for (size_t i = 0; i < outer.size(); ++i) {
    area2 += Cross(outer[i] - outer[0], outer[(i + 1) % outer.size()] - outer[0]);
  }
  const double len = Length(area2);
  if (!(len > 0.0)) return false;
  Vec3d u, w;
  OrthonormalBasis(area2 / len, &u, &w);
  auto point = [&](const ContourVertex& v) -> const Vec3d& { return contours[v.contour][v.index]; };
  auto q = [&](const ContourVertex& v) {
    const Vec3d& p = point(v);
    return std::pair<double, double>{Dot(p, u), Dot(p, w)};
  };
  auto signed_area = [&](const std::vector<ContourVertex>& r) {
    double s = 0;
    for (size_t i = 0; i < r.size(); ++i) {
      const auto [x0, y0] = q(r[i]);
      const auto [x1, y1] = q(r[(i + 1) % r.size()]);
      s += x0 * y1 - x1 * y0;
    }
    return s;
  };
  auto contour = [&](size_t k) {
    std::vector<ContourVertex> r(contours[k].size());
    for (size_t i = 0; i < r.size(); ++i) {
      r[i] = {static_cast<uint32_t>(k), static_cast<uint32_t>(i)};
    }
    return r;
  };
  *merged = contour(0);
  std::vector<std::pair<double, size_t>> order;  // (max u, hole index)
  for (size_t k = 1; k < contours.size(); ++k) {
    double mx = -std::numeric_limits<double>::infinity();
    for (const ContourVertex& v : contour(k)) mx = std::max(mx, q(v).first);
    order.emplace_back(mx, k);
  }
  std::sort(order.begin(), order.end(), std::greater<>());
  for (const auto& [mx, k] : order) {
    std::vector<ContourVertex> hole = contour(k);
    if (signed_area(hole) > 0.0) std::reverse(hole.begin(), hole.end());  // holes run clockwise
    size_t m = 0;
    for (size_t i = 1; i < hole.size(); ++i) {
      if (q(hole[i]).first > q(hole[m]).first) m = i;
    }
    // Plain variables, not a structured binding: lambdas below capture them (clang 14).
    const double hx = q(hole[m]).first, hy = q(hole[m]).second;
    // Nearest crossing of the ray y = hy, x >= hx with an edge of the merged contour.
    double best_x = std::numeric_limits<double>::infinity();
    size_t best = kNone;
    const size_t n = merged->size();
    for (size_t i = 0; i < n; ++i) {
      const auto [ax, ay] = q((*merged)[i]);
      const auto [bx, by] = q((*merged)[(i + 1) % n]);
      if (ay == by || hy < std::min(ay, by) || hy > std::max(ay, by)) continue;
      const double x = ax + (hy - ay) * (bx - ax) / (by - ay);
      if (x >= hx && x < best_x) {
        best_x = x;
        best = ax > bx ? i : (i + 1) % n;
      }
    }
    if (best == kNone) {
      ++*ignored_holes;  // the hole lies outside the outer contour
      continue;
    }
    // A contour vertex inside the triangle (M, crossing, P) could block the bridge: take the
    // one with the smallest angle to the ray instead. Vertices that occur twice (the seam of
    // an earlier bridge) are only usable at the copy whose interior angle contains the bridge
    // direction ("locally inside"), otherwise the spliced contour would cross itself.
    auto orient = [](double ax, double ay, double bx, double by, double cx, double cy) {
      return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    };
    auto locally_inside = [&](size_t i) {
      const auto [ax, ay] = q((*merged)[(i + n - 1) % n]);
      const auto [bx, by] = q((*merged)[i]);
      const auto [cx, cy] = q((*merged)[(i + 1) % n]);
      const double left_of_in = orient(ax, ay, bx, by, hx, hy);
      const double left_of_out = orient(bx, by, cx, cy, hx, hy);
      return orient(ax, ay, bx, by, cx, cy) >= 0.0 ? (left_of_in >= 0.0 && left_of_out >= 0.0)
                                                   : (left_of_in >= 0.0 || left_of_out >= 0.0);
    };
    const auto [px, py] = q((*merged)[best]);
    const size_t hit = best;
    double best_tan = std::numeric_limits<double>::infinity();
    bool found = false;
    for (size_t i = 0; i < n; ++i) {
      const auto [vx, vy] = q((*merged)[i]);
      const bool is_hit = vx == px && vy == py;
      if (!is_hit) {
        if (!(vx > hx)) continue;
        const double o1 = orient(hx, hy, best_x, hy, vx, vy);
        const double o2 = orient(best_x, hy, px, py, vx, vy);
        const double o3 = orient(px, py, hx, hy, vx, vy);
        const bool inside = (o1 >= 0 && o2 >= 0 && o3 >= 0) || (o1 <= 0 && o2 <= 0 && o3 <= 0);
        if (!inside) continue;
      }
      if (!locally_inside(i)) continue;
      const double t = vx > hx ? std::abs(vy - hy) / (vx - hx) : std::numeric_limits<double>::max();
      if (!found || t < best_tan) {
        best_tan = t;
        best = i;
        found = true;
      }
    }
    if (!found) best = hit;
    std::vector<ContourVertex> insert;
    insert.reserve(hole.size() + 2);
    for (size_t i = 0; i <= hole.size(); ++i) insert.push_back(hole[(m + i) % hole.size()]);
    insert.push_back((*merged)[best]);
    merged->insert(merged->begin() + static_cast<std::ptrdiff_t>(best) + 1, insert.begin(), insert.end());
  }
  return true;
}

}  // namespace pf::geometry
