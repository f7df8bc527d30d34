// NURBS curves and surfaces with resolved control points: point and first
// derivative by de Boor's algorithm on homogeneous points (Piegl & Tiller,
// The NURBS Book, 1997: A3.1, A4.1; the derivative as a curve of degree p - 1,
// eq. 3.3), and the closest parameter of a curve to a point.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace core {

// A curve with its control points in model space (a NurbsCurve's bindings
// resolved on a mesh, drivers applied).
struct CurveGeometry {
  int degree = 3;
  std::vector<double> knots;    // points + degree + 1, non-decreasing
  Eigen::MatrixX3d points;      // #P by 3 control points, model units
  std::vector<double> weights;  // empty: all 1
  double domainStart() const { return knots[static_cast<std::size_t>(degree)]; }
  double domainEnd() const { return knots[static_cast<std::size_t>(points.rows())]; }
};

// The curve's point at parameter u (clamped to the domain).
Eigen::Vector3d curvePoint(const CurveGeometry& curve, double u);

// dC/du at u (clamped to the domain); model units per unit of parameter.
Eigen::Vector3d curveDerivative(const CurveGeometry& curve, double u);

// Closest points on one curve for many queries: dense samples found once,
// then a golden-section search between the neighbours of the nearest sample.
class CurveClosestParameter {
 public:
  // samples_per_span: samples in each non-empty knot span (>= 2).
  explicit CurveClosestParameter(const CurveGeometry& curve, int samples_per_span = 16);
  // The parameter of the curve point closest to p (ties: the smaller parameter).
  double closestParameter(const Eigen::Vector3d& p) const;

 private:
  const CurveGeometry& curve_;
  std::vector<double> parameters_;
  std::vector<Eigen::Vector3d> samples_;
};

// A surface with its control grid in model space: count_u * count_v points,
// index i * count_v + j.
struct SurfaceGeometry {
  int degree_u = 3, degree_v = 3;
  std::vector<double> knots_u, knots_v;
  int count_u = 0, count_v = 0;
  Eigen::MatrixX3d points;      // #(count_u * count_v) by 3
  std::vector<double> weights;  // empty: all 1
};

// The surface's point at (u, v) (each clamped to its domain).
Eigen::Vector3d surfacePoint(const SurfaceGeometry& surface, double u, double v);

}  // namespace core
