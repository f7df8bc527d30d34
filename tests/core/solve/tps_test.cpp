#include "core/base/parallel.h"
#include "core/solve/tps.h"

#include <cmath>

#include <gtest/gtest.h>

#include "tests/test_support.h"

namespace {

using rigport_test::matricesNear;
using rigport_test::randomPoints;

// A smooth non-linear deformation used as ground truth.
Eigen::MatrixX3d bend(const Eigen::MatrixX3d& p) {
  Eigen::MatrixX3d q = p;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    q(i, 0) += 0.1 * std::sin(p(i, 1));
    q(i, 1) += 0.05 * p(i, 0) * p(i, 2);
    q(i, 2) += 0.08 * p(i, 0) * p(i, 0);
  }
  return q;
}

TEST(Tps, ReproducesLandmarksExactlyWithoutRegularization) {
  for (int n : {4, 10, 44, 68, 300}) {
    const Eigen::MatrixX3d p = randomPoints(n, 7u + static_cast<unsigned>(n), 10.0);
    const Eigen::MatrixX3d q = bend(p);
    auto warp = core::fitTps(p, q);
    ASSERT_TRUE(warp) << warp.error().message;
    EXPECT_TRUE(matricesNear(warp->apply(p), q, 1e-9 * 10.0)) << "n = " << n;
  }
}

TEST(Tps, ReproducesAnAffineMapExactlyWithZeroBendingEnergy) {
  const Eigen::MatrixX3d p = randomPoints(40, 3, 5.0);
  Eigen::Matrix3d A;
  A << 1.3, 0.2, -0.1, 0.05, 0.9, 0.3, -0.2, 0.1, 1.1;
  const Eigen::RowVector3d t(3.0, -2.0, 0.5);
  const Eigen::MatrixX3d q = (p * A.transpose()).rowwise() + t;
  auto warp = core::fitTps(p, q);
  ASSERT_TRUE(warp) << warp.error().message;
  EXPECT_LT(warp->kernelWeights().cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(warp->bendingEnergy(), 0.0, 1e-12);
  // Off the landmarks too, and the Jacobian is A everywhere.
  const Eigen::MatrixX3d x = randomPoints(500, 4, 8.0);
  EXPECT_TRUE(matricesNear(warp->apply(x), (x * A.transpose()).rowwise() + t, 1e-9));
  for (const auto& j : warp->jacobians(x.topRows(20))) EXPECT_TRUE(matricesNear(j, A, 1e-9));
}

TEST(Tps, NonAffineWarpHasPositiveBendingEnergy) {
  const Eigen::MatrixX3d p = randomPoints(30, 5, 2.0);
  auto warp = core::fitTps(p, bend(p));
  ASSERT_TRUE(warp);
  EXPECT_GT(warp->bendingEnergy(), 1e-6);
}

TEST(Tps, FactorisationReuseEqualsFreshSolve) {
  const Eigen::MatrixX3d p = randomPoints(68, 11, 10.0);
  auto factorization = core::TpsFactorization::create(p);
  ASSERT_TRUE(factorization) << factorization.error().message;
  const Eigen::MatrixX3d x = randomPoints(1000, 12, 12.0);
  for (unsigned s = 0; s < 3; ++s) {
    Eigen::MatrixX3d q = bend(p) + 0.3 * randomPoints(68, 20 + s);
    const core::TpsWarp reused = factorization->fit(q);
    auto fresh = core::fitTps(p, q);
    ASSERT_TRUE(fresh);
    EXPECT_TRUE(matricesNear(reused.apply(x), fresh->apply(x), 1e-9));
  }
}

TEST(Tps, BendingEnergyMatrixGivesTheWeightsAndTheEnergyOfAFit) {
  const Eigen::MatrixX3d p = randomPoints(50, 13, 4.0);
  const Eigen::MatrixX3d q = bend(p);
  for (double regularization : {0.0, 0.05}) {
    core::TpsOptions options;
    options.regularization = regularization;
    auto factorization = core::TpsFactorization::create(p, options);
    ASSERT_TRUE(factorization) << factorization.error().message;
    const Eigen::MatrixXd b = factorization->bendingEnergyMatrix();
    ASSERT_EQ(b.rows(), 50);
    EXPECT_TRUE(b.isApprox(b.transpose(), 1e-12));
    const core::TpsWarp warp = factorization->fit(q);
    EXPECT_TRUE(matricesNear(warp.kernelWeights(), -b * q, 1e-9)) << "regularization " << regularization;
    // Affine maps cost nothing.
    Eigen::MatrixXd affine(50, 4);
    affine << p, Eigen::VectorXd::Ones(50);
    EXPECT_LT((b * affine).cwiseAbs().maxCoeff(), 1e-9);
    if (regularization == 0.0) {
      EXPECT_NEAR((q.transpose() * b * q).trace(), warp.bendingEnergy(), 1e-9 * warp.bendingEnergy());
    }
  }
}

TEST(Tps, SinglePrecisionBendingMatrixIsCloseToTheDoubleOne) {
  // Regularised as the dense maps are (well conditioned): formed in float.
  const Eigen::MatrixX3d p = randomPoints(300, 31, 10.0);
  core::TpsOptions options;
  options.regularization = 0.05;
  auto regularised = core::TpsFactorization::create(p, options);
  ASSERT_TRUE(regularised);
  using Precision = core::TpsFactorization::BendingPrecision;
  const Eigen::MatrixXd b = regularised->bendingEnergyMatrix();
  const Eigen::MatrixXd single = regularised->bendingEnergyMatrix(Precision::kSingle);
  EXPECT_FALSE(single == b) << "the float inverse was not used";
  EXPECT_LT((single - b).cwiseAbs().maxCoeff(), 1e-5 * b.cwiseAbs().maxCoeff());
  // Unregularised, every centre with a twin 2e-5 away (near the duplicate
  // tolerance): whichever way the inverse is formed, B stays close.
  Eigen::MatrixX3d clustered(600, 3);
  clustered << p, p.array() + 2e-5;
  auto plain = core::TpsFactorization::create(clustered);
  ASSERT_TRUE(plain);
  const Eigen::MatrixXd b_plain = plain->bendingEnergyMatrix();
  EXPECT_LT((plain->bendingEnergyMatrix(Precision::kSingle) - b_plain).cwiseAbs().maxCoeff(),
            1e-5 * b_plain.cwiseAbs().maxCoeff());
}

TEST(Tps, JacobianMatchesFiniteDifferences) {
  const Eigen::MatrixX3d p = randomPoints(20, 21, 3.0);
  auto warp = core::fitTps(p, bend(p));
  ASSERT_TRUE(warp);
  const Eigen::MatrixX3d x = randomPoints(50, 22, 3.0);
  const auto jac = warp->jacobians(x);
  const double h = 1e-6;
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    Eigen::Matrix3d fd;
    for (int c = 0; c < 3; ++c) {
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e(c) = h;
      const Eigen::Vector3d xp = x.row(i).transpose();
      fd.col(c) = (warp->apply(Eigen::Vector3d(xp + e)) - warp->apply(Eigen::Vector3d(xp - e))) / (2 * h);
    }
    EXPECT_TRUE(matricesNear(jac[static_cast<std::size_t>(i)], fd, 1e-5)) << "point " << i;
  }
}

TEST(Tps, BatchEvaluationDoesNotDependOnThreadCount) {
  const Eigen::MatrixX3d p = randomPoints(68, 31, 10.0);
  auto warp = core::fitTps(p, bend(p));
  ASSERT_TRUE(warp);
  const Eigen::MatrixX3d x = randomPoints(5000, 32, 10.0);
  auto applyOn = [&](int threads) {
    const core::ScopedThreadCount scope(threads);
    return warp->apply(x);
  };
  EXPECT_TRUE(matricesNear(applyOn(1), applyOn(2), 0.0));
}

// The batch kernels have an AVX2 clone chosen at load time; it must give the
// same bits as plain scalar code with the documented summation order, so that
// outputs do not depend on the machine a job runs on.
TEST(Tps, BatchEvaluationIsBitIdenticalToScalarReference) {
  const Eigen::MatrixX3d p = randomPoints(465, 33, 10.0);
  auto warp = core::fitTps(p, bend(p));
  ASSERT_TRUE(warp);
  const Eigen::MatrixX3d x = randomPoints(1001, 34, 12.0);
  const Eigen::MatrixX3d out = warp->apply(x);
  const auto jac = warp->jacobians(x);
  const Eigen::MatrixX3d& c = warp->centres();
  const Eigen::MatrixX3d& w = warp->kernelWeights();
  const Eigen::Matrix<double, 4, 3>& a = warp->affine();
  int value_mismatches = 0, jacobian_mismatches = 0;
  for (Eigen::Index k = 0; k < x.rows(); ++k) {
    double s[3] = {0, 0, 0}, g[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    for (Eigen::Index i = 0; i < c.rows(); ++i) {
      const double dx = x(k, 0) - c(i, 0), dy = x(k, 1) - c(i, 1), dz = x(k, 2) - c(i, 2);
      const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
      const double inv = 1.0 / std::sqrt(dx * dx + dy * dy + dz * dz + 1e-300);
      const double u[3] = {dx * inv, dy * inv, dz * inv};
      for (int d = 0; d < 3; ++d) {
        s[d] += w(i, d) * r;
        for (int e = 0; e < 3; ++e) g[3 * d + e] += w(i, d) * u[e];
      }
    }
    for (int d = 0; d < 3; ++d) {
      const double v = s[d] + a(0, d) * x(k, 0) + a(1, d) * x(k, 1) + a(2, d) * x(k, 2) + a(3, d);
      if (v != out(k, d)) ++value_mismatches;
      for (int e = 0; e < 3; ++e) {
        if (g[3 * d + e] + a(e, d) != jac[static_cast<std::size_t>(k)](d, e)) ++jacobian_mismatches;
      }
    }
  }
  EXPECT_EQ(value_mismatches, 0);
  EXPECT_EQ(jacobian_mismatches, 0);
}

TEST(Tps, RegularizationTradesLandmarkFitForSmoothness) {
  const Eigen::MatrixX3d p = randomPoints(50, 41, 10.0);
  const Eigen::MatrixX3d q = bend(p) + 0.2 * randomPoints(50, 42);
  auto exact = core::fitTps(p, q);
  core::TpsOptions smooth;
  smooth.regularization = 5.0;
  auto approx = core::fitTps(p, q, smooth);
  ASSERT_TRUE(exact && approx);
  EXPECT_LT(approx->bendingEnergy(), exact->bendingEnergy());
  EXPECT_GT((approx->apply(p) - q).norm(), 1e-3);
}

TEST(Tps, LeaveOneOutMatchesExplicitRefit) {
  const Eigen::MatrixX3d p = randomPoints(30, 51, 5.0);
  const Eigen::MatrixX3d q = bend(p);
  for (double lambda : {0.0, 0.5}) {
    core::TpsOptions opts;
    opts.regularization = lambda;
    auto f = core::TpsFactorization::create(p, opts);
    ASSERT_TRUE(f);
    const auto loo = f->leaveOneOut(q);
    ASSERT_EQ(loo.residuals.size(), 30u);
    for (int i = 0; i < 30; i += 7) {
      Eigen::MatrixX3d p_minus(29, 3), q_minus(29, 3);
      for (int j = 0, k = 0; j < 30; ++j) {
        if (j == i) continue;
        p_minus.row(k) = p.row(j);
        q_minus.row(k++) = q.row(j);
      }
      auto w = core::fitTps(p_minus, q_minus, opts);
      ASSERT_TRUE(w);
      const double expected = (w->apply(Eigen::Vector3d(p.row(i).transpose())) - q.row(i).transpose()).norm();
      EXPECT_NEAR(loo.residuals[static_cast<std::size_t>(i)], expected, 1e-8 * (1 + expected)) << "landmark " << i;
    }
  }
}

// Smooth at the scale of the landmark spacing, like a change of identity.
Eigen::MatrixX3d gentleBend(const Eigen::MatrixX3d& p) {
  Eigen::MatrixX3d q = 1.2 * p;
  for (Eigen::Index i = 0; i < p.rows(); ++i) {
    q(i, 0) += 0.5 * std::sin(0.2 * p(i, 1));
    q(i, 2) += 0.02 * p(i, 0) * p(i, 0);
  }
  return q;
}

TEST(Tps, ConsistentLandmarksFlagNothing) {
  const Eigen::MatrixX3d p = randomPoints(68, 61, 10.0);
  auto f = core::TpsFactorization::create(p);
  ASSERT_TRUE(f);
  EXPECT_TRUE(f->leaveOneOut(gentleBend(p)).suspicious.empty());
  EXPECT_TRUE(f->leaveOneOut(p).suspicious.empty());  // identity: all residuals ~0
}

TEST(Tps, SwappedLandmarkPairIsFlagged) {
  const Eigen::MatrixX3d p = randomPoints(68, 71, 10.0);
  Eigen::MatrixX3d q = gentleBend(p);
  q.row(10).swap(q.row(40));
  auto f = core::TpsFactorization::create(p);
  ASSERT_TRUE(f);
  const auto loo = f->leaveOneOut(q);
  EXPECT_NE(std::find(loo.suspicious.begin(), loo.suspicious.end(), 10), loo.suspicious.end());
  EXPECT_NE(std::find(loo.suspicious.begin(), loo.suspicious.end(), 40), loo.suspicious.end());
  EXPECT_EQ(loo.suspicious.size(), 2u);
}

TEST(Tps, RejectsTooFewDuplicateAndCoplanarLandmarks) {
  auto few = core::TpsFactorization::create(randomPoints(3, 1));
  ASSERT_FALSE(few);
  EXPECT_EQ(few.error().code, core::ErrorCode::kInvalidLandmarks);

  Eigen::MatrixX3d dup = randomPoints(10, 2);
  dup.row(7) = dup.row(3);
  auto d = core::TpsFactorization::create(dup, {}, {"a", "b", "c", "nose_tip", "e", "f", "g", "chin", "i", "j"});
  ASSERT_FALSE(d);
  EXPECT_EQ(d.error().code, core::ErrorCode::kIllConditioned);
  EXPECT_NE(d.error().message.find("'nose_tip'"), std::string::npos) << d.error().message;
  EXPECT_NE(d.error().message.find("'chin'"), std::string::npos) << d.error().message;

  Eigen::MatrixX3d flat = randomPoints(12, 3);
  flat.col(2).setConstant(1.0);
  auto c = core::TpsFactorization::create(flat);
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().code, core::ErrorCode::kIllConditioned);
  EXPECT_NE(c.error().message.find("coplanar"), std::string::npos);

  flat.col(2) = 1e-6 * randomPoints(12, 4).col(0);  // nearly coplanar
  EXPECT_FALSE(core::TpsFactorization::create(flat));
}

}  // namespace
