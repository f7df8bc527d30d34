#include "core/components/cluster.h"

#include <numbers>

#include <gtest/gtest.h>

namespace {

TEST(Cluster, TransformsAboutThePivotByMemberWeight) {
  const Eigen::Vector3d pivot(1.0, 0.0, 0.0);
  const Eigen::Matrix3d rotation = core::eulerDegreesToRotation({0.0, 0.0, 90.0});
  const Eigen::Affine3d t = core::clusterTransform(pivot, {0.0, 0.0, 0.5}, rotation, {2.0, 1.0, 1.0});
  Eigen::MatrixX3d points(3, 3);
  points << 2, 0, 0,  // pivot + x: scaled to 2x, turned to +y, lifted
      1, 0, 0,        // the pivot itself: only translated
      0, 5, 0;        // not a member
  Eigen::MatrixX3d out = points;
  core::applyCluster(out, {{0, 1.0}, {1, 0.5}}, t);
  EXPECT_LT((out.row(0) - Eigen::RowVector3d(1.0, 2.0, 0.5)).norm(), 1e-12);
  EXPECT_LT((out.row(1) - Eigen::RowVector3d(1.0, 0.0, 0.25)).norm(), 1e-12);  // half the motion
  EXPECT_EQ(out.row(2), points.row(2));
}

TEST(Cluster, EulerDegreesApplyXThenYThenZ) {
  const Eigen::Matrix3d r = core::eulerDegreesToRotation({90.0, 90.0, 0.0});
  // y -> (X 90) z -> (Y 90) x
  EXPECT_LT((r * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitX()).norm(), 1e-12);
}

TEST(Muscle, AxialScaleContractsTowardTheOriginAlongTheAxisOnly) {
  const Eigen::Vector3d origin(0, 0, 0), insertion(2, 0, 0);
  const Eigen::Affine3d t = core::muscleTransform(origin, insertion, 0.25, core::MuscleDriveMode::kAxialScale, 1.0);
  EXPECT_LT((t * insertion - Eigen::Vector3d(1.5, 0, 0)).norm(), 1e-12);           // scaled by 1 - c
  EXPECT_LT((t * Eigen::Vector3d(1, 3, -2) - Eigen::Vector3d(0.75, 3, -2)).norm(), 1e-12);  // across the axis: kept
  EXPECT_LT((t * origin - origin).norm(), 1e-12);
  const Eigen::Affine3d half = core::muscleTransform(origin, insertion, 0.25, core::MuscleDriveMode::kAxialScale, 0.5);
  EXPECT_LT((half * insertion - Eigen::Vector3d(1.75, 0, 0)).norm(), 1e-12);
}

TEST(Muscle, TranslateSlidesTowardTheOrigin) {
  const Eigen::Affine3d t = core::muscleTransform({1, 1, 0}, {1, 3, 0}, 0.5, core::MuscleDriveMode::kTranslate, 1.0);
  EXPECT_LT((t * Eigen::Vector3d(4, 4, 4) - Eigen::Vector3d(4, 3, 4)).norm(), 1e-12);
}

}  // namespace
