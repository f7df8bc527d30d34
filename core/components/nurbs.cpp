// NURBS evaluation: de Boor on homogeneous points (Piegl & Tiller 1997).
#include "core/components/nurbs.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

namespace core {

namespace {

using HomogeneousPoints = std::vector<Eigen::Vector4d>;  // (w*x, w*y, w*z, w)

// The span k with knots[k] <= u < knots[k+1], degree <= k < count; the last
// non-empty span at the domain's end.
int findSpan(int degree, const std::vector<double>& knots, int count, double u) {
  if (u >= knots[static_cast<std::size_t>(count)]) {
    int k = count - 1;
    while (k > degree && !(knots[static_cast<std::size_t>(k)] < knots[static_cast<std::size_t>(k) + 1])) --k;
    return k;
  }
  const auto begin = knots.begin() + degree;
  const auto end = knots.begin() + count + 1;
  const int k = static_cast<int>(std::upper_bound(begin, end, u) - knots.begin()) - 1;
  return std::clamp(k, degree, count - 1);
}

Eigen::Vector4d deBoor(int degree, const std::vector<double>& knots, const HomogeneousPoints& points, double u) {
  const int count = static_cast<int>(points.size());
  u = std::clamp(u, knots[static_cast<std::size_t>(degree)], knots[static_cast<std::size_t>(count)]);
  const int k = findSpan(degree, knots, count, u);
  std::vector<Eigen::Vector4d> d(static_cast<std::size_t>(degree) + 1);
  for (int j = 0; j <= degree; ++j) d[static_cast<std::size_t>(j)] = points[static_cast<std::size_t>(j + k - degree)];
  for (int r = 1; r <= degree; ++r) {
    for (int j = degree; j >= r; --j) {
      const double lo = knots[static_cast<std::size_t>(j + k - degree)];
      const double hi = knots[static_cast<std::size_t>(j + 1 + k - r)];
      const double alpha = hi > lo ? (u - lo) / (hi - lo) : 0.0;
      d[static_cast<std::size_t>(j)] = (1.0 - alpha) * d[static_cast<std::size_t>(j) - 1] + alpha * d[static_cast<std::size_t>(j)];
    }
  }
  return d[static_cast<std::size_t>(degree)];
}

HomogeneousPoints homogeneous(const Eigen::MatrixX3d& points, const std::vector<double>& weights) {
  HomogeneousPoints h(static_cast<std::size_t>(points.rows()));
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[static_cast<std::size_t>(i)];
    h[static_cast<std::size_t>(i)] << w * points.row(i).transpose(), w;
  }
  return h;
}

// The derivative of a homogeneous B-spline: degree - 1, control points
// degree * (P[i+1] - P[i]) / (knots[i+degree+1] - knots[i+1]), knots trimmed at both ends.
void derivativeCurve(int degree, const std::vector<double>& knots, const HomogeneousPoints& points,
                     std::vector<double>& d_knots, HomogeneousPoints& d_points) {
  d_knots.assign(knots.begin() + 1, knots.end() - 1);
  d_points.resize(points.size() - 1);
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    const double span = knots[i + static_cast<std::size_t>(degree) + 1] - knots[i + 1];
    d_points[i] = span > 0.0 ? Eigen::Vector4d(degree * (points[i + 1] - points[i]) / span) : Eigen::Vector4d::Zero();
  }
}

}  // namespace

// Linear non-rational curves (the muscle rig's wires; paper 001 section 4.3.2
// chose them for speed): de Boor's single step without building homogeneous
// copies of the points, the same arithmetic as the general path.
static bool isPlainPolyline(const CurveGeometry& curve) { return curve.degree == 1 && curve.weights.empty(); }

static Eigen::Vector3d polylinePoint(const CurveGeometry& curve, double u) {
  const int count = static_cast<int>(curve.points.rows());
  u = std::clamp(u, curve.knots[1], curve.knots[static_cast<std::size_t>(count)]);
  const int k = findSpan(1, curve.knots, count, u);
  const double lo = curve.knots[static_cast<std::size_t>(k)], hi = curve.knots[static_cast<std::size_t>(k) + 1];
  const double alpha = hi > lo ? (u - lo) / (hi - lo) : 0.0;
  return (1.0 - alpha) * curve.points.row(k - 1).transpose() + alpha * curve.points.row(k).transpose();
}

Eigen::Vector3d curvePoint(const CurveGeometry& curve, double u) {
  if (isPlainPolyline(curve)) return polylinePoint(curve, u);
  const Eigen::Vector4d h = deBoor(curve.degree, curve.knots, homogeneous(curve.points, curve.weights), u);
  return h.head<3>() / h(3);
}

Eigen::Vector3d curveDerivative(const CurveGeometry& curve, double u) {
  if (isPlainPolyline(curve)) {  // the degree-0 derivative curve's value: the span's slope
    const int count = static_cast<int>(curve.points.rows());
    u = std::clamp(u, curve.knots[1], curve.knots[static_cast<std::size_t>(count)]);
    const int k = findSpan(1, curve.knots, count, u);
    const double span = curve.knots[static_cast<std::size_t>(k) + 1] - curve.knots[static_cast<std::size_t>(k)];
    return span > 0.0 ? Eigen::Vector3d((curve.points.row(k) - curve.points.row(k - 1)).transpose() / span)
                      : Eigen::Vector3d::Zero();
  }
  const HomogeneousPoints h = homogeneous(curve.points, curve.weights);
  const Eigen::Vector4d a = deBoor(curve.degree, curve.knots, h, u);
  std::vector<double> d_knots;
  HomogeneousPoints d_points;
  derivativeCurve(curve.degree, curve.knots, h, d_knots, d_points);
  const Eigen::Vector4d da = deBoor(curve.degree - 1, d_knots, d_points, u);
  // C = A / w  =>  C' = (A' - w' C) / w
  const Eigen::Vector3d c = a.head<3>() / a(3);
  return (da.head<3>() - da(3) * c) / a(3);
}

CurveClosestParameter::CurveClosestParameter(const CurveGeometry& curve, int samples_per_span) : curve_(curve) {
  samples_per_span = std::max(samples_per_span, 2);
  const int count = static_cast<int>(curve.points.rows());
  for (int k = curve.degree; k < count; ++k) {
    const double lo = curve.knots[static_cast<std::size_t>(k)];
    const double hi = curve.knots[static_cast<std::size_t>(k) + 1];
    if (!(hi > lo)) continue;
    for (int s = 0; s < samples_per_span; ++s) parameters_.push_back(lo + (hi - lo) * s / samples_per_span);
  }
  parameters_.push_back(curve.domainEnd());
  samples_.reserve(parameters_.size());
  for (double u : parameters_) samples_.push_back(curvePoint(curve, u));
}

// Linear non-rational curves: each segment's exact projection, the closest
// kept (ties: the smaller parameter), what the search below converges to.
static double polylineClosestParameter(const CurveGeometry& curve, const Eigen::Vector3d& p) {
  const int count = static_cast<int>(curve.points.rows());
  double best_u = curve.domainStart();
  double best_sq = std::numeric_limits<double>::infinity();
  for (int k = 1; k < count; ++k) {
    const double lo = curve.knots[static_cast<std::size_t>(k)], hi = curve.knots[static_cast<std::size_t>(k) + 1];
    if (!(hi > lo)) continue;
    const Eigen::Vector3d a = curve.points.row(k - 1).transpose(), d = curve.points.row(k).transpose() - a;
    const double length_sq = d.squaredNorm();
    const double t = length_sq > 0.0 ? std::clamp((p - a).dot(d) / length_sq, 0.0, 1.0) : 0.0;
    const double sq = (a + t * d - p).squaredNorm();
    if (sq < best_sq) {
      best_sq = sq;
      best_u = lo + t * (hi - lo);
    }
  }
  return best_u;
}

double CurveClosestParameter::closestParameter(const Eigen::Vector3d& p) const {
  if (isPlainPolyline(curve_)) return polylineClosestParameter(curve_, p);
  std::size_t best = 0;
  double best_sq = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    const double sq = (samples_[i] - p).squaredNorm();
    if (sq < best_sq) {
      best_sq = sq;
      best = i;
    }
  }
  double a = parameters_[best > 0 ? best - 1 : 0];
  double b = parameters_[std::min(best + 1, parameters_.size() - 1)];
  // Golden-section search of |C(u) - p|^2 between the neighbouring samples,
  // where it is unimodal when the samples are dense enough.
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  auto sq = [&](double u) { return (curvePoint(curve_, u) - p).squaredNorm(); };
  double x1 = b - ratio * (b - a), x2 = a + ratio * (b - a);
  double f1 = sq(x1), f2 = sq(x2);
  for (int it = 0; it < 60 && b - a > 1e-13 * (1.0 + std::abs(a)); ++it) {
    if (f1 <= f2) {
      b = x2;
      x2 = x1;
      f2 = f1;
      x1 = b - ratio * (b - a);
      f1 = sq(x1);
    } else {
      a = x1;
      x1 = x2;
      f1 = f2;
      x2 = a + ratio * (b - a);
      f2 = sq(x2);
    }
  }
  // The golden section finds the minimum to about sqrt(machine epsilon) in u
  // (the distance is flat there); Gauss-Newton steps on C'(u) . (C(u) - p) = 0
  // finish it, each kept only when it stays in the bracket and gets closer.
  const double lo = parameters_[best > 0 ? best - 1 : 0];
  const double hi = parameters_[std::min(best + 1, parameters_.size() - 1)];
  // Progress is judged by |C'(u) . (C(u) - p)|, which unlike the flat
  // distance still resolves there.
  auto slope = [&](double at, Eigen::Vector3d& derivative) {
    derivative = curveDerivative(curve_, at);
    return derivative.dot(curvePoint(curve_, at) - p);
  };
  double u = 0.5 * (a + b);
  Eigen::Vector3d d;
  double g = slope(u, d);
  for (int it = 0; it < 4 && d.squaredNorm() > 0.0; ++it) {
    const double next = std::clamp(u - g / d.squaredNorm(), lo, hi);
    Eigen::Vector3d d_next;
    const double g_next = slope(next, d_next);
    if (!(std::abs(g_next) < std::abs(g))) break;
    u = next;
    g = g_next;
    d = d_next;
  }
  return sq(u) <= best_sq ? u : parameters_[best];
}

Eigen::Vector3d surfacePoint(const SurfaceGeometry& surface, double u, double v) {
  assert(surface.points.rows() == static_cast<Eigen::Index>(surface.count_u) * surface.count_v);
  const HomogeneousPoints h = homogeneous(surface.points, surface.weights);
  HomogeneousPoints column(static_cast<std::size_t>(surface.count_u));
  HomogeneousPoints row(static_cast<std::size_t>(surface.count_v));
  for (int i = 0; i < surface.count_u; ++i) {
    for (int j = 0; j < surface.count_v; ++j) {
      row[static_cast<std::size_t>(j)] = h[static_cast<std::size_t>(i * surface.count_v + j)];
    }
    column[static_cast<std::size_t>(i)] = deBoor(surface.degree_v, surface.knots_v, row, v);
  }
  const Eigen::Vector4d p = deBoor(surface.degree_u, surface.knots_u, column, u);
  return p.head<3>() / p(3);
}

}  // namespace core
