// Point-triangle closest point, shared by the closest-point indices
// (core/geometry/closest_point.cpp, core/geometry/moving_mesh_index.cpp) so that both give
// bit-identical answers. Internal to core: callers use closestPointOnTriangle()
// or an index.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/closest_point.h"
#include "core/base/parallel.h"

namespace core::point_triangle {

using Vec3 = Eigen::Vector3d;

// Plain 3-vector for the hot path: fixed-size Eigen 3-vectors compile to
// shuffle-heavy SSE code here; plain scalars take fewer instructions.
struct P3 {
  double x, y, z;
};
inline P3 operator-(const P3& a, const P3& b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline P3 operator+(const P3& a, const P3& b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline P3 operator*(double s, const P3& a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(const P3& a, const P3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline P3 cross(const P3& a, const P3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline P3 toP3(const Vec3& v) { return {v.x(), v.y(), v.z()}; }
inline bool isFinite(const P3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }
inline Vec3 toVec3(const P3& v) { return {v.x, v.y, v.z}; }

// Closest point of p on one triangle: squared distance, barycentrics, point.
struct TriHit {
  double sq_distance = std::numeric_limits<double>::infinity();
  double bary[3] = {0.0, 0.0, 0.0};
  P3 point{0.0, 0.0, 0.0};
};

inline void setHit(TriHit& h, const P3& p, const P3& point, double u, double v, double w) {
  h.point = point;
  h.bary[0] = u;
  h.bary[1] = v;
  h.bary[2] = w;
  const P3 d = p - point;
  h.sq_distance = dot(d, d);
}

// Below this ratio |ab x ac|^2 / (max edge)^4 (sin^2 of the flattest angle,
// roughly) Ericson's interior barycentrics lose digits to cancellation; the
// edge fallback is then evaluated too and the closer answer kept.
constexpr double kSliverRatio = 1e-6;

// Closest point over the three edges as segments: the answer for collinear
// triangles (zero-length edges allowed).
inline TriHit closestOnEdges(const P3& p, const P3& a, const P3& b, const P3& c) {
  TriHit best;
  const P3* corners[3] = {&a, &b, &c};
  for (int i = 0; i < 3; ++i) {
    const int j = (i + 1) % 3;
    const P3 e = *corners[j] - *corners[i];
    const double len2 = dot(e, e);
    const double t = len2 > 0.0 ? std::clamp(dot(p - *corners[i], e) / len2, 0.0, 1.0) : 0.0;
    TriHit h;
    double bary[3] = {0.0, 0.0, 0.0};
    bary[i] = 1.0 - t;
    bary[j] = t;
    setHit(h, p, *corners[i] + t * e, bary[0], bary[1], bary[2]);
    if (i == 0 || h.sq_distance < best.sq_distance) best = h;
  }
  return best;
}

// True when Ericson's region method is accurate for (a, b, c). A pure function
// of the corners, so the index can precompute it and stay bit-identical to
// closestPointOnTriangle().
inline bool isWellShaped(const P3& a, const P3& b, const P3& c) {
  const P3 ab = b - a;
  const P3 ac = c - a;
  const P3 bc = c - b;
  const P3 n = cross(ab, ac);
  const double e2 = std::max({dot(ab, ab), dot(ac, ac), dot(bc, bc)});
  return dot(n, n) > kSliverRatio * e2 * e2;  // false for NaN and for zero-length edges
}

// Ericson 2005, 5.1.5 (Voronoi regions of corners, edges, face).
inline TriHit closestOnTriangle(const P3& p, const P3& a, const P3& b, const P3& c, bool well_shaped) {
  TriHit r;
  const P3 ab = b - a;
  const P3 ac = c - a;
  const P3 ap = p - a;
  const double d1 = dot(ab, ap);
  const double d2 = dot(ac, ap);
  // Divisions are guarded: their denominators are squared edge lengths
  // mathematically, but may round to 0 on degenerate input.
  auto ratio = [](double num, double den) { return den > 0.0 ? std::clamp(num / den, 0.0, 1.0) : 0.0; };
  do {
    if (d1 <= 0.0 && d2 <= 0.0) {
      setHit(r, p, a, 1.0, 0.0, 0.0);
      break;
    }
    const P3 bp = p - b;
    const double d3 = dot(ab, bp);
    const double d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) {
      setHit(r, p, b, 0.0, 1.0, 0.0);
      break;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
      const double v = ratio(d1, d1 - d3);
      setHit(r, p, a + v * ab, 1.0 - v, v, 0.0);
      break;
    }
    const P3 cp = p - c;
    const double d5 = dot(ab, cp);
    const double d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) {
      setHit(r, p, c, 0.0, 0.0, 1.0);
      break;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
      const double w = ratio(d2, d2 - d6);
      setHit(r, p, a + w * ac, 1.0 - w, 0.0, w);
      break;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
      const double w = ratio(d4 - d3, (d4 - d3) + (d5 - d6));
      setHit(r, p, b + w * (c - b), 0.0, 1.0 - w, w);
      break;
    }
    // Face interior. Rounding can leave one of va, vb, vc slightly negative;
    // clamping keeps the barycentrics a convex combination.
    const double ua = std::max(va, 0.0);
    const double ub = std::max(vb, 0.0);
    const double uc = std::max(vc, 0.0);
    const double sum = ua + ub + uc;
    if (!(sum > 0.0 && sum < std::numeric_limits<double>::infinity())) {
      well_shaped = false;  // collinear: only the edge answer is meaningful
      break;              // r stays at infinite distance
    }
    const double v = ub / sum;
    const double w = uc / sum;
    setHit(r, p, a + v * ab + w * ac, std::max(0.0, 1.0 - v - w), v, w);
  } while (false);
  if (well_shaped) return r;
  const TriHit e = closestOnEdges(p, a, b, c);
  return r.sq_distance <= e.sq_distance ? r : e;  // NaN in r selects the edges
}

inline SurfacePoint toSurfacePoint(const TriHit& h, int face) {
  SurfacePoint s;
  s.face = face;
  s.barycentric = Vec3(h.bary[0], h.bary[1], h.bary[2]);
  s.point = toVec3(h.point);
  s.sq_distance = h.sq_distance;
  return s;
}

inline Vec3 row(const Eigen::MatrixX3d& m, Eigen::Index i) { return Vec3(m(i, 0), m(i, 1), m(i, 2)); }

// ClosestPointOptions as a search uses them, converted once per batch (the
// cosine is not free per query).
struct Limits {
  explicit Limits(const ClosestPointOptions& options)
      : max_distance(options.max_distance),
        min_cos(options.max_normal_angle_deg < 180.0 ? std::cos(options.max_normal_angle_deg * (std::numbers::pi / 180.0))
                                                     : -2.0) {}
  double max_distance;
  double min_cos;  // -2: no normal filter
};

// A face as the indices store it: corners (double, as given), unit normal
// (as computeFaceNormals), the caller's face number, and whether Ericson's
// region method is accurate for it.
struct Face {
  P3 a, b, c;
  P3 n;
  std::int32_t id = -1;
  bool well_shaped = false;
};

// The face f of (positions, triangles) when it is usable: distinct, finite
// corners and twice-area above (1e-10 * diagonal)^2, as isDegenerateTriangle().
inline bool makeFace(const Eigen::MatrixX3d& positions, const Eigen::MatrixX3i& triangles, Eigen::Index f,
                     double degenerate_eps, Face& face) {
  const int i0 = triangles(f, 0), i1 = triangles(f, 1), i2 = triangles(f, 2);
  if (i0 == i1 || i1 == i2 || i0 == i2) return false;
  face.a = toP3(row(positions, i0));
  face.b = toP3(row(positions, i1));
  face.c = toP3(row(positions, i2));
  if (!(isFinite(face.a) && isFinite(face.b) && isFinite(face.c))) return false;
  const P3 n = cross(face.b - face.a, face.c - face.a);
  const double len = std::sqrt(dot(n, n));
  if (len <= degenerate_eps * degenerate_eps) return false;
  face.n = {n.x / len, n.y / len, n.z / len};
  face.id = static_cast<std::int32_t>(f);
  face.well_shaped = isWellShaped(face.a, face.b, face.c);
  return true;
}

// A batch as both indices run it: row i of `queries` with the normal and
// label mask of row i of `filters` (each used when given for every row), in
// parallel chunks; query(q, normal or nullptr, mask, limits) answers one.
template <class Query>
std::vector<SurfacePoint> queryRows(const Eigen::MatrixX3d& queries, const ClosestPointOptions& options,
                                    const ClosestPointFilters& filters, const Query& query) {
  const Eigen::Index nq = queries.rows();
  const bool use_normals = filters.normals.rows() == nq && nq > 0;
  const bool use_masks = static_cast<Eigen::Index>(filters.label_masks.size()) == nq;
  std::vector<SurfacePoint> out(static_cast<std::size_t>(nq));
  const Limits limits(options);
  parallelFor(nq, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t i = begin; i < end; ++i) {
      const Vec3 q = row(queries, i);
      Vec3 n;
      if (use_normals) n = row(filters.normals, i);
      const std::uint64_t mask = use_masks ? filters.label_masks[static_cast<std::size_t>(i)] : ~std::uint64_t{0};
      out[static_cast<std::size_t>(i)] = query(q, use_normals ? &n : nullptr, mask, limits);
    }
  });
  return out;
}

}  // namespace core::point_triangle
