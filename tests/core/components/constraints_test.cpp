#include "core/components/constraints.h"

#include <Eigen/LU>
#include <gtest/gtest.h>

namespace {

TEST(PointConstraint, WeightsAreNormalised) {
  Eigen::MatrixX3d targets(2, 3);
  targets << 0, 0, 0, 4, 8, 0;
  const Eigen::Vector3d a = core::weightedAverage(targets, {1.0, 3.0});
  EXPECT_LT((a - Eigen::Vector3d(3, 6, 0)).norm(), 1e-12);
  const Eigen::Vector3d b = core::weightedAverage(targets, {10.0, 30.0});  // same ratio, same point
  EXPECT_LT((a - b).norm(), 1e-12);
  const Eigen::Vector3d one = core::weightedAverage(targets, {0.0, 2.0});
  EXPECT_LT((one - Eigen::Vector3d(4, 8, 0)).norm(), 1e-12);
}

TEST(AimConstraint, AimAxisPointsAtTheTargetUpAxisStaysUp) {
  const Eigen::Vector3d position(1, 2, 3), target(4, 6, 3);
  const Eigen::Vector3d aim(0, 0, 1), up(0, 1, 0), world_up(0, 0, 1);
  const Eigen::Matrix3d r = core::aimRotation(position, target, aim, up, world_up);
  EXPECT_LT((r * r.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
  EXPECT_LT((r * aim - (target - position).normalized()).norm(), 1e-12);
  // The aim is horizontal, so the up axis can point straight up.
  EXPECT_LT((r * up - world_up).norm(), 1e-12);
}

TEST(AimConstraint, UpAxisIsWorldUpProjectedOffTheAim) {
  const Eigen::Vector3d aim(1, 0, 0), up(0, 0, 1);
  const Eigen::Vector3d direction = Eigen::Vector3d(1, 0, 1).normalized();
  const Eigen::Matrix3d r = core::aimRotation(Eigen::Vector3d::Zero(), direction, aim, up, Eigen::Vector3d::UnitZ());
  EXPECT_LT((r * aim - direction).norm(), 1e-12);
  EXPECT_LT((r * up - Eigen::Vector3d(-1, 0, 1).normalized()).norm(), 1e-12);
}

TEST(AimConstraint, WorldUpAlongTheAimStillGivesARotation) {
  const Eigen::Matrix3d r = core::aimRotation(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 5), Eigen::Vector3d::UnitX(),
                                              Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(r.allFinite());
  EXPECT_LT((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(r.determinant(), 1.0, 1e-12);
}

}  // namespace
