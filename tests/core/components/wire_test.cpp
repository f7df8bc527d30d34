#include "core/components/wire.h"

#include <gtest/gtest.h>

namespace {

// A straight cubic along x from -1 to 1 at y = z = 0.
core::CurveGeometry straightCurve() {
  core::CurveGeometry c;
  c.degree = 3;
  c.knots = {0, 0, 0, 0, 1, 1, 1, 1};
  c.points.resize(4, 3);
  c.points << -1, 0, 0, -1.0 / 3, 0, 0, 1.0 / 3, 0, 0, 1, 0, 0;
  return c;
}

core::Wire plainWire(double d0) {
  core::Wire w;
  w.name = "w";
  w.dropoff_distance = d0;
  w.rotation = 0.0;
  w.scale = 0.0;
  return w;
}

TEST(Wire, DropoffIsOneAtZeroZeroAtOneWithFlatEnds) {
  EXPECT_DOUBLE_EQ(core::wireDropoff(0.0), 1.0);
  EXPECT_DOUBLE_EQ(core::wireDropoff(1.0), 0.0);
  EXPECT_DOUBLE_EQ(core::wireDropoff(1.5), 0.0);
  EXPECT_DOUBLE_EQ(core::wireDropoff(0.5), 0.5625);  // (1 - 0.25)^2
  const double h = 1e-6;
  EXPECT_NEAR((core::wireDropoff(h) - core::wireDropoff(0.0)) / h, 0.0, 1e-5);
  EXPECT_NEAR((core::wireDropoff(1.0) - core::wireDropoff(1.0 - h)) / h, 0.0, 1e-5);
  // In between the slope is not flat: f'(0.5) = -4 * 0.5 * 0.75 = -1.5.
  EXPECT_NEAR((core::wireDropoff(0.5 + h) - core::wireDropoff(0.5 - h)) / (2 * h), -1.5, 1e-6);
}

TEST(Wire, PointOnTheCurveMovesByTheCurveOffset) {
  const core::CurveGeometry base = straightCurve();
  core::CurveGeometry deformed = base;
  deformed.points.col(1) += Eigen::Vector4d(0.0, 0.3, 0.3, 0.0);  // middle raised in y
  Eigen::MatrixX3d points(1, 3);
  points << 0.2, 0.0, 0.0;
  Eigen::MatrixX3d out = points;
  core::evaluateWire(out, base, deformed, plainWire(0.5));
  // u = 0.6 on the base (x = 2u - 1); the offset there is deformed(u) - base(u).
  const Eigen::Vector3d offset = core::curvePoint(deformed, 0.6) - core::curvePoint(base, 0.6);
  EXPECT_GT(offset.norm(), 0.1);
  EXPECT_LT((out.row(0).transpose() - (points.row(0).transpose() + offset)).norm(), 1e-9);
}

TEST(Wire, InfluenceFallsOffAndStopsAtTheDropoffDistance) {
  const core::CurveGeometry base = straightCurve();
  core::CurveGeometry deformed = base;
  deformed.points.col(2) += Eigen::Vector4d::Constant(0.1);  // whole curve moved by 0.1 in z
  Eigen::MatrixX3d points(4, 3);
  points << 0.0, 0.25, 0.0,  // d = d0 / 2
      0.0, 0.5, 0.0,         // d = d0
      0.0, 0.7, 0.0,         // beyond
      0.3, 0.0, 0.4;         // d = d0 * 0.8 in z
  Eigen::MatrixX3d out = points;
  core::evaluateWire(out, base, deformed, plainWire(0.5));
  EXPECT_NEAR(out(0, 2), 0.1 * 0.5625, 1e-12);
  EXPECT_EQ(out.row(1), points.row(1));
  EXPECT_EQ(out.row(2), points.row(2));
  const double x = 0.8;
  EXPECT_NEAR(out(3, 2) - 0.4, 0.1 * (1 - x * x) * (1 - x * x), 1e-12);
  EXPECT_NEAR(out(0, 0), 0.0, 1e-12);
}

TEST(Wire, EnvelopeScalesAndMembersRestrict) {
  const core::CurveGeometry base = straightCurve();
  core::CurveGeometry deformed = base;
  deformed.points.col(2) += Eigen::Vector4d::Constant(0.1);
  Eigen::MatrixX3d points(2, 3);
  points << 0, 0, 0, 0.5, 0, 0;
  core::Wire w = plainWire(0.5);
  w.envelope = 0.5;
  w.members = {1};
  Eigen::MatrixX3d out = points;
  core::evaluateWire(out, base, deformed, w);
  EXPECT_EQ(out.row(0), points.row(0));
  EXPECT_NEAR(out(1, 2), 0.05, 1e-12);
}

TEST(Wire, RotationTurnsTheOffsetWithTheCurve) {
  const core::CurveGeometry base = straightCurve();
  core::CurveGeometry deformed = base;
  // The deformed curve: the base turned 90 degrees about z (along y).
  for (Eigen::Index i = 0; i < 4; ++i) deformed.points.row(i) << 0.0, base.points(i, 0), 0.0;
  Eigen::MatrixX3d points(1, 3);
  points << 0.0, 0.0, 0.1;  // offset along z: turning about z keeps it
  Eigen::MatrixX3d points_y(1, 3);
  points_y << 0.0, 0.1, 0.0;  // offset along y: turns to -x
  core::Wire w = plainWire(1.0);
  w.rotation = 1.0;
  const double f = core::wireDropoff(0.1);
  Eigen::MatrixX3d out = points_y;
  core::evaluateWire(out, base, deformed, w);
  // move = f * ((curve offset 0) + (R r - r)), R r = (-0.1, 0, 0)
  EXPECT_NEAR(out(0, 0), f * -0.1, 1e-9);
  EXPECT_NEAR(out(0, 1), 0.1 + f * -0.1, 1e-9);
  Eigen::MatrixX3d out_z = points;
  core::evaluateWire(out_z, base, deformed, w);
  EXPECT_LT((out_z - points).norm(), 1e-9);
}

}  // namespace
