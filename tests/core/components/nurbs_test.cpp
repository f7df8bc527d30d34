#include "core/components/nurbs.h"

#include <gtest/gtest.h>

namespace {

core::CurveGeometry cubicBezier() {
  core::CurveGeometry c;
  c.degree = 3;
  c.knots = {0, 0, 0, 0, 1, 1, 1, 1};
  c.points.resize(4, 3);
  c.points << 0, 0, 0, 1, 2, 0, 3, 2, 1, 4, 0, 0;
  return c;
}

TEST(Nurbs, CubicBezierMatchesBernsteinForm) {
  const core::CurveGeometry c = cubicBezier();
  for (double u : {0.0, 0.25, 0.5, 0.8, 1.0}) {
    const double b0 = (1 - u) * (1 - u) * (1 - u), b1 = 3 * u * (1 - u) * (1 - u), b2 = 3 * u * u * (1 - u), b3 = u * u * u;
    const Eigen::Vector3d expected = (b0 * c.points.row(0) + b1 * c.points.row(1) + b2 * c.points.row(2) + b3 * c.points.row(3)).transpose();
    EXPECT_LT((core::curvePoint(c, u) - expected).norm(), 1e-12) << "u = " << u;
  }
}

TEST(Nurbs, DerivativeMatchesFiniteDifferencesAlsoWhenRational) {
  core::CurveGeometry c = cubicBezier();
  for (int rational = 0; rational < 2; ++rational) {
    if (rational) c.weights = {1.0, 2.0, 0.5, 1.0};
    for (double u : {0.1, 0.5, 0.9}) {
      const double h = 1e-6;
      const Eigen::Vector3d fd = (core::curvePoint(c, u + h) - core::curvePoint(c, u - h)) / (2 * h);
      EXPECT_LT((core::curveDerivative(c, u) - fd).norm(), 1e-6) << "u = " << u << " rational " << rational;
    }
  }
}

TEST(Nurbs, RationalQuarterCircleLiesOnTheCircle) {
  core::CurveGeometry c;
  c.degree = 2;
  c.knots = {0, 0, 0, 1, 1, 1};
  c.points.resize(3, 3);
  c.points << 1, 0, 0, 1, 1, 0, 0, 1, 0;
  c.weights = {1.0, std::sqrt(0.5), 1.0};
  for (double u = 0.0; u <= 1.0; u += 0.125) EXPECT_NEAR(core::curvePoint(c, u).norm(), 1.0, 1e-12) << u;
}

TEST(Nurbs, LinearCurveIsThePolylineAndClosestParameterProjects) {
  core::CurveGeometry c;
  c.degree = 1;
  c.knots = {0, 0, 1, 2, 2};
  c.points.resize(3, 3);
  c.points << 0, 0, 0, 1, 0, 0, 1, 1, 0;
  EXPECT_LT((core::curvePoint(c, 0.5) - Eigen::Vector3d(0.5, 0, 0)).norm(), 1e-12);
  EXPECT_LT((core::curvePoint(c, 1.25) - Eigen::Vector3d(1, 0.25, 0)).norm(), 1e-12);
  const core::CurveClosestParameter closest(c);
  EXPECT_NEAR(closest.closestParameter({0.3, -0.4, 0.2}), 0.3, 1e-9);
  EXPECT_NEAR(closest.closestParameter({1.7, 0.6, 0.0}), 1.6, 1e-9);
  EXPECT_NEAR(closest.closestParameter({-5, 0, 0}), 0.0, 1e-12);  // beyond the end: the end
}

TEST(Nurbs, ClosestParameterOnCubicIsAStationaryPoint) {
  const core::CurveGeometry c = cubicBezier();
  const core::CurveClosestParameter closest(c);
  const Eigen::Vector3d p(2.0, 2.5, 0.3);
  const double u = closest.closestParameter(p);
  // The offset is normal to the curve there, and no sample is closer.
  EXPECT_NEAR((core::curvePoint(c, u) - p).dot(core::curveDerivative(c, u).normalized()), 0.0, 1e-7);
  for (double v = 0.0; v <= 1.0; v += 0.001) EXPECT_GE((core::curvePoint(c, v) - p).norm() + 1e-12, (core::curvePoint(c, u) - p).norm());
}

TEST(Nurbs, BilinearSurfaceInterpolatesItsCorners) {
  core::SurfaceGeometry s;
  s.degree_u = s.degree_v = 1;
  s.knots_u = s.knots_v = {0, 0, 1, 1};
  s.count_u = s.count_v = 2;
  s.points.resize(4, 3);
  s.points << 0, 0, 0, 0, 1, 0, 1, 0, 0, 1, 1, 1;  // (i, j) = (u, v) corners; (1, 1) raised
  EXPECT_LT((core::surfacePoint(s, 0.5, 0.5) - Eigen::Vector3d(0.5, 0.5, 0.25)).norm(), 1e-12);
  EXPECT_LT((core::surfacePoint(s, 1.0, 0.0) - Eigen::Vector3d(1, 0, 0)).norm(), 1e-12);
}

}  // namespace
