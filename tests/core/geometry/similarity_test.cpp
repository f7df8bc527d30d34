#include "core/geometry/similarity.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;
using rigport_test::randomPoints;

TEST(Similarity, RecoversRotationScaleAndTranslation) {
  const Eigen::MatrixX3d source = randomPoints(20, 1);
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, -2.0, 0.5).normalized()).toRotationMatrix();
  const Eigen::Vector3d shift(0.3, -1.0, 2.0);
  const Eigen::MatrixX3d target = ((1.8 * source * rotation.transpose()).rowwise() + shift.transpose()).eval();
  const core::Similarity s = core::fitSimilarity(source, target);
  EXPECT_NEAR(s.scale, 1.8, 1e-12);
  EXPECT_TRUE(matricesNear(s.rotation, rotation, 1e-12));
  EXPECT_TRUE(matricesNear(s.translation, shift, 1e-12));
  EXPECT_LT(s.rms_residual, 1e-12);
}

TEST(AffineMap, RecoversAnAffineMapAndMeasuresTheMisfit) {
  const Eigen::MatrixX3d source = randomPoints(30, 2);
  Eigen::Matrix3d linear;
  linear << 2.0, 0.3, 0.0, -0.2, 1.0, 0.1, 0.0, 0.4, 0.7;
  const Eigen::Vector3d shift(1.0, 2.0, -3.0);
  Eigen::MatrixX3d target = ((source * linear.transpose()).rowwise() + shift.transpose()).eval();
  const auto exact = core::fitAffine(source, target);
  ASSERT_TRUE(exact);
  EXPECT_TRUE(matricesNear(exact->linear, linear, 1e-12));
  EXPECT_TRUE(matricesNear(exact->translation, shift, 1e-12));
  EXPECT_LT(exact->rms_residual, 1e-12);
  // A shape the map cannot explain leaves a misfit.
  target.row(0) += Eigen::RowVector3d(0.5, 0.0, 0.0);
  const auto bent = core::fitAffine(source, target);
  ASSERT_TRUE(bent);
  EXPECT_GT(bent->rms_residual, 0.01);
}

TEST(AffineMap, IsUndeterminedForPointsThatDoNotSpanSpace) {
  Eigen::MatrixX3d flat = randomPoints(12, 3);
  flat.col(2).setConstant(0.5);  // a plane: the map across it is free
  EXPECT_FALSE(core::fitAffine(flat, flat));
  const Eigen::MatrixX3d three = randomPoints(3, 4);
  EXPECT_FALSE(core::fitAffine(three, three));
  const Eigen::MatrixX3d four = randomPoints(4, 5);
  EXPECT_TRUE(core::fitAffine(four, four));
}

}  // namespace
