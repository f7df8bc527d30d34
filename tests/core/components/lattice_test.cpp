#include "core/components/lattice.h"

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

core::Lattice box() {
  core::Lattice l;
  l.name = "box";
  l.origin = {-1.0, -0.5, 0.0};
  l.axes << 2.0, 0.5, 0.0,  // S = (2, 0, 0), T = (0.5, 1, 0) (sheared), U = (0, 0, 1.5)
      0.0, 1.0, 0.0,        //
      0.0, 0.0, 1.5;
  l.divisions = {4, 3, 2};
  return l;
}

TEST(Lattice, BernsteinPolynomialsSumToOne) {
  for (double t : {0.0, 0.3, 1.0}) {
    double sum = 0.0;
    for (int i = 0; i <= 4; ++i) sum += core::bernstein(4, i, t);
    EXPECT_NEAR(sum, 1.0, 1e-14);
  }
  EXPECT_DOUBLE_EQ(core::bernstein(3, 1, 0.5), 0.375);  // 3 * 0.5 * 0.25
}

TEST(Lattice, RestLatticeIsTheIdentity) {
  const core::Lattice l = box();
  const Eigen::MatrixX3d points = rigport_test::randomPoints(200, 7, 1.5);
  const Eigen::MatrixX3d out = core::evaluateLattice(points, l, core::latticeRestPoints(l));
  EXPECT_EQ(out, points);
  // The local coordinates reproduce the rest grid.
  const auto rest = core::latticeRestPoints(l);
  EXPECT_LT((core::latticeCoordinates(l, rest[(2 * 3 + 1) * 2 + 1]) - Eigen::Vector3d(2.0 / 3, 0.5, 1.0)).norm(), 1e-12);
}

TEST(Lattice, OneMovedPointMovesPointsByItsBernsteinWeight) {
  const core::Lattice l = box();
  auto deformed = core::latticeRestPoints(l);
  const int i = 1, j = 2, k = 0;
  const Eigen::Vector3d move(0.1, -0.2, 0.3);
  deformed[static_cast<std::size_t>((i * 3 + j) * 2 + k)] += move;
  const Eigen::Vector3d stu(0.25, 0.6, 0.4);
  Eigen::MatrixX3d points(2, 3);
  points.row(0) = (l.origin + l.axes * stu).transpose();
  points.row(1) << 5.0, 5.0, 5.0;  // outside: untouched
  const Eigen::MatrixX3d out = core::evaluateLattice(points, l, deformed);
  // B_1^3(0.25) B_2^2(0.6) B_0^1(0.4), by hand: 3*0.25*0.75^2 = 0.421875; 0.36; 0.6.
  const double weight = 0.421875 * 0.36 * 0.6;
  EXPECT_LT((out.row(0) - points.row(0) - weight * move.transpose()).norm(), 1e-12);
  EXPECT_EQ(out.row(1), points.row(1));
}

TEST(Lattice, MovingEveryPointAffinelyMovesPointsAffinely) {
  // Linear precision: an affine map of the whole lattice is that map inside it.
  const core::Lattice l = box();
  auto deformed = core::latticeRestPoints(l);
  Eigen::Matrix3d a;
  a << 1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.1, 1.2;
  const Eigen::Vector3d b(0.05, -0.02, 0.1);
  for (auto& p : deformed) p = a * p + b;
  Eigen::MatrixX3d points(1, 3);
  points.row(0) = (l.origin + l.axes * Eigen::Vector3d(0.3, 0.7, 0.2)).transpose();
  const Eigen::MatrixX3d out = core::evaluateLattice(points, l, deformed);
  EXPECT_LT((out.row(0).transpose() - (a * points.row(0).transpose() + b)).norm(), 1e-12);
}

}  // namespace
