#include "core/solve/rbf.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;

constexpr core::RbfKernel kKernels[] = {core::RbfKernel::kGaussian, core::RbfKernel::kMultiquadric,
                                        core::RbfKernel::kThinPlate, core::RbfKernel::kLinear};

// Points in a 0.2-wide cube (face-sized in metres).
Eigen::MatrixX3d randomPoints(int n, unsigned seed) { return rigport_test::randomPoints(n, seed, 0.1); }

Eigen::MatrixXd distances(const Eigen::MatrixX3d& a, const Eigen::MatrixX3d& b) {
  Eigen::MatrixXd d(a.rows(), b.rows());
  for (Eigen::Index i = 0; i < a.rows(); ++i) {
    for (Eigen::Index j = 0; j < b.rows(); ++j) d(i, j) = (a.row(i) - b.row(j)).norm();
  }
  return d;
}

Eigen::MatrixXd randomValues(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, 0.01);
  Eigen::MatrixXd v(rows, cols);
  for (int i = 0; i < rows; ++i) for (int j = 0; j < cols; ++j) v(i, j) = n(rng);
  return v;
}

core::RbfOptions optionsFor(core::RbfKernel kernel) {
  core::RbfOptions o;
  o.kernel = kernel;
  o.gamma = 0.05;
  return o;
}

// Residual of the fit at the centres for `values`.
double centreResidual(const core::RbfFactorization& f, const Eigen::MatrixXd& values) {
  return (core::RbfFactorization::evaluate(f.centreBasis(), f.solve(values)) - values).cwiseAbs().maxCoeff();
}

TEST(Rbf, ReproducesCentreValuesExactlyForEveryKernelAndFrame) {
  const Eigen::MatrixX3d centres = randomPoints(20, 1);
  const Eigen::MatrixXd values = randomValues(20, 3 * 50, 2);  // 50 frames of xyz displacements
  for (core::RbfKernel kernel : kKernels) {
    auto f = core::RbfFactorization::create(distances(centres, centres), centres, optionsFor(kernel));
    ASSERT_TRUE(f) << core::rbfKernelName(kernel) << ": " << f.error().message;
    const Eigen::MatrixXd weights = f->solve(values);
    ASSERT_EQ(weights.rows(), 20 + f->polynomialTerms());
    // Through the public evaluation path (basis of the centres as points).
    auto basis = f->basis(distances(centres, centres), centres);
    ASSERT_TRUE(basis);
    EXPECT_TRUE(matricesNear(core::RbfFactorization::evaluate(*basis, weights), values, 1e-10)) << core::rbfKernelName(kernel);
    // Elsewhere: finite.
    const Eigen::MatrixX3d points = randomPoints(300, 3);
    auto pb = f->basis(distances(points, centres), points);
    ASSERT_TRUE(pb);
    EXPECT_TRUE(core::RbfFactorization::evaluate(*pb, weights).allFinite()) << core::rbfKernelName(kernel);
  }
}

TEST(Rbf, SolvingAllFramesAtOnceEqualsFrameByFrame) {
  const Eigen::MatrixX3d centres = randomPoints(15, 4);
  const Eigen::MatrixXd values = randomValues(15, 3 * 8, 5);
  auto f = core::RbfFactorization::create(distances(centres, centres), centres, optionsFor(core::RbfKernel::kGaussian));
  ASSERT_TRUE(f);
  const Eigen::MatrixXd all = f->solve(values);
  for (Eigen::Index c = 0; c < values.cols(); ++c) {
    EXPECT_TRUE(matricesNear(f->solve(values.col(c)), all.col(c), 1e-12)) << "column " << c;
  }
}

TEST(Rbf, StiffnessTradesFitForSmoothnessAndGrowsTheResidual) {
  const Eigen::MatrixX3d centres = randomPoints(20, 6);
  const Eigen::MatrixXd values = randomValues(20, 6, 7);
  for (core::RbfKernel kernel : kKernels) {
    double previous = -1.0;
    for (double s : {1.0, 3.0, 6.0, 9.0}) {
      core::RbfOptions o = optionsFor(kernel);
      o.stiffness.assign(20, s);
      auto f = core::RbfFactorization::create(distances(centres, centres), centres, o);
      ASSERT_TRUE(f) << core::rbfKernelName(kernel) << " stiffness " << s << ": " << f.error().message;
      const double residual = centreResidual(*f, values);
      if (s == 1.0) {
        EXPECT_LT(residual, 1e-10) << core::rbfKernelName(kernel);
      } else {
        EXPECT_GT(residual, previous) << core::rbfKernelName(kernel) << " stiffness " << s;
        EXPECT_LT(residual, 2.0 * values.cwiseAbs().maxCoeff()) << core::rbfKernelName(kernel);
      }
      previous = residual;
    }
  }
  // One stiff centre: only it (mostly) misses its value.
  core::RbfOptions o = optionsFor(core::RbfKernel::kGaussian);
  o.stiffness.assign(20, 1.0);
  o.stiffness[3] = 9.0;
  auto f = core::RbfFactorization::create(distances(centres, centres), centres, o);
  ASSERT_TRUE(f);
  const Eigen::MatrixXd err = core::RbfFactorization::evaluate(f->centreBasis(), f->solve(values)) - values;
  EXPECT_GT(err.row(3).cwiseAbs().maxCoeff(), 1e-6);
  Eigen::MatrixXd others = err;
  others.row(3).setZero();
  EXPECT_LT(others.cwiseAbs().maxCoeff(), 1e-10);
}

TEST(Rbf, AffinePolynomialReproducesAffineFieldsEverywhere) {
  const Eigen::MatrixX3d centres = randomPoints(12, 8);
  Eigen::Matrix3d a;
  a << 0.1, -0.2, 0.05, 0.3, 0.0, -0.1, 0.02, 0.07, 0.2;
  const Eigen::RowVector3d b(0.01, -0.02, 0.03);
  const Eigen::MatrixXd values = ((centres * a.transpose()).rowwise() + b).eval();
  const Eigen::MatrixX3d points = randomPoints(100, 9);
  const Eigen::MatrixXd expected = ((points * a.transpose()).rowwise() + b).eval();
  for (core::RbfKernel kernel : kKernels) {
    core::RbfOptions o = optionsFor(kernel);
    o.polynomial = core::RbfPolynomial::kAffine;
    auto f = core::RbfFactorization::create(distances(centres, centres), centres, o);
    ASSERT_TRUE(f) << f.error().message;
    auto basis = f->basis(distances(points, centres), points);
    ASSERT_TRUE(basis);
    EXPECT_TRUE(matricesNear(core::RbfFactorization::evaluate(*basis, f->solve(values)), expected, 1e-9))
        << core::rbfKernelName(kernel);
  }
}

TEST(Rbf, ConstantPolynomialReproducesConstantFieldsWithoutPositions) {
  const Eigen::MatrixX3d centres = randomPoints(12, 10);
  const Eigen::MatrixXd values = Eigen::MatrixXd::Constant(12, 3, 0.004);
  const Eigen::MatrixX3d points = randomPoints(100, 11);
  const Eigen::MatrixX3d none;
  for (core::RbfKernel kernel : kKernels) {
    core::RbfOptions o = optionsFor(kernel);
    o.polynomial = core::RbfPolynomial::kConstant;  // the geodesic setting: distances only
    auto f = core::RbfFactorization::create(distances(centres, centres), none, o);
    ASSERT_TRUE(f) << f.error().message;
    auto basis = f->basis(distances(points, centres), none);
    ASSERT_TRUE(basis);
    EXPECT_TRUE(matricesNear(core::RbfFactorization::evaluate(*basis, f->solve(values)),
                             Eigen::MatrixXd::Constant(100, 3, 0.004), 1e-12))
        << core::rbfKernelName(kernel);
  }
  // kAuto without positions: thin-plate falls back to a constant term.
  auto tp = core::RbfFactorization::create(distances(centres, centres), none, optionsFor(core::RbfKernel::kThinPlate));
  ASSERT_TRUE(tp);
  EXPECT_EQ(tp->polynomial(), core::RbfPolynomial::kConstant);
  auto g = core::RbfFactorization::create(distances(centres, centres), none, optionsFor(core::RbfKernel::kGaussian));
  ASSERT_TRUE(g);
  EXPECT_EQ(g->polynomialTerms(), 0);
}

TEST(Rbf, GaussianIsExpOfMinusDistanceOverGamma) {
  // Paper 002 eq. 5.1, exactly as written.
  EXPECT_DOUBLE_EQ(core::rbfKernelValue(core::RbfKernel::kGaussian, 2.0, 3.0), std::exp(-1.5));
  EXPECT_DOUBLE_EQ(core::rbfKernelValue(core::RbfKernel::kMultiquadric, 4.0, 3.0), 5.0);
  EXPECT_DOUBLE_EQ(core::rbfKernelValue(core::RbfKernel::kThinPlate, 1.0, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(core::rbfKernelValue(core::RbfKernel::kThinPlate, 1.0, std::exp(1.0)), std::exp(2.0));
  EXPECT_DOUBLE_EQ(core::rbfKernelValue(core::RbfKernel::kGaussian, 1.0, std::numeric_limits<double>::infinity()), 0.0);
}

TEST(Rbf, BadInputsGiveClearErrors) {
  const Eigen::MatrixX3d centres = randomPoints(8, 12);
  const Eigen::MatrixXd d = distances(centres, centres);

  Eigen::MatrixX3d duplicated = centres;
  duplicated.row(5) = duplicated.row(2);
  auto dup = core::RbfFactorization::create(distances(duplicated, duplicated), duplicated, optionsFor(core::RbfKernel::kGaussian));
  ASSERT_FALSE(dup);
  EXPECT_EQ(dup.error().code, core::ErrorCode::kIllConditioned);
  EXPECT_NE(dup.error().message.find("singular"), std::string::npos) << dup.error().message;

  Eigen::MatrixXd nan = d;
  nan(1, 4) = std::numeric_limits<double>::quiet_NaN();
  auto n = core::RbfFactorization::create(nan, centres, optionsFor(core::RbfKernel::kGaussian));
  ASSERT_FALSE(n);
  EXPECT_EQ(n.error().code, core::ErrorCode::kInvalidArgument);
  EXPECT_NE(n.error().message.find("centres 1 and 4"), std::string::npos) << n.error().message;

  core::RbfOptions zero_gamma = optionsFor(core::RbfKernel::kGaussian);
  zero_gamma.gamma = 0.0;
  EXPECT_FALSE(core::RbfFactorization::create(d, centres, zero_gamma));

  core::RbfOptions bad_stiffness = optionsFor(core::RbfKernel::kGaussian);
  bad_stiffness.stiffness.assign(8, 1.0);
  bad_stiffness.stiffness[2] = 10.0;
  auto s = core::RbfFactorization::create(d, centres, bad_stiffness);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("1-9"), std::string::npos) << s.error().message;

  core::RbfOptions affine = optionsFor(core::RbfKernel::kThinPlate);
  affine.polynomial = core::RbfPolynomial::kAffine;
  EXPECT_FALSE(core::RbfFactorization::create(d, Eigen::MatrixX3d(), affine));

  EXPECT_FALSE(core::RbfFactorization::create(Eigen::MatrixXd(3, 4), Eigen::MatrixX3d(), optionsFor(core::RbfKernel::kLinear)));

  // Unreachable points: no influence with the gaussian, an error otherwise.
  Eigen::MatrixXd points_d = d.topRows(2);
  points_d(1, 3) = std::numeric_limits<double>::infinity();
  auto g = core::RbfFactorization::create(d, centres, optionsFor(core::RbfKernel::kGaussian));
  ASSERT_TRUE(g);
  auto gb = g->basis(points_d, centres.topRows(2));
  ASSERT_TRUE(gb);
  EXPECT_EQ((*gb)(1, 3), 0.0);
  auto l = core::RbfFactorization::create(d, centres, optionsFor(core::RbfKernel::kLinear));
  ASSERT_TRUE(l);
  auto lb = l->basis(points_d, centres.topRows(2));
  ASSERT_FALSE(lb);
  EXPECT_NE(lb.error().message.find("point 1 to centre 3"), std::string::npos) << lb.error().message;
  points_d(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(g->basis(points_d, centres.topRows(2)));
}

TEST(Rbf, FactorisationIsSharedByCopies) {
  const Eigen::MatrixX3d centres = randomPoints(10, 13);
  auto f = core::RbfFactorization::create(distances(centres, centres), centres, optionsFor(core::RbfKernel::kGaussian));
  ASSERT_TRUE(f);
  const core::RbfFactorization copy = *f;
  EXPECT_EQ(&copy.centreBasis(), &f->centreBasis());
  EXPECT_GT(copy.conditionEstimate(), 1.0);
}

}  // namespace
