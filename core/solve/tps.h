// Thin-plate spline warp in 3D (Bookstein 1989; papers 004 eq. 1-3, 000 ch. 4.7.1):
//   f(x) = sum_i w_i U(|x - p_i|) + A x + b,   U(r) = r,
// with the (n+4)x(n+4) system [K P; P^T 0][w; a] = [q; 0].
//
// Fit once, apply many: TpsFactorization depends only on the source centres p
// (this is what the service caches per source rig); fit() back-substitutes any
// number of target right-hand sides q and returns an immutable TpsWarp.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"

namespace core {

struct TpsOptions {
  // Approximating TPS: lambda added to the kernel diagonal (model units); 0 interpolates the landmarks exactly.
  double regularization = 0.0;
  // Compute leave-one-out residuals (O(n^3) once per factorisation); off for large dense centre sets.
  bool leave_one_out = true;
  // Centres closer than this fraction of their bounding-box diagonal are duplicates.
  double duplicate_tolerance = 1e-6;
  // The system is rejected when the centres' thinnest extent (smallest principal axis / largest) is below this.
  double min_flatness = 1e-3;
  // A landmark is suspicious when the spline through the others misses it by this times its nearest spacing.
  double outlier_spacing_ratio = 1.0;
};

// An immutable warp R^3 -> R^3. Safe to share between threads.
class TpsWarp {
 public:
  TpsWarp() = default;
  TpsWarp(Eigen::MatrixX3d centres, Eigen::MatrixX3d kernel_weights, Eigen::Matrix<double, 4, 3> affine);

  // #P by 3 points -> #P by 3 warped points.
  Eigen::MatrixX3d apply(const Eigen::MatrixX3d& points) const;
  Eigen::Vector3d apply(const Eigen::Vector3d& point) const;

  // Jacobian df/dx at each point: #P 3x3 matrices (row-major: J(r, c) = d f_r / d x_c).
  std::vector<Eigen::Matrix3d> jacobians(const Eigen::MatrixX3d& points) const;
  Eigen::Matrix3d jacobian(const Eigen::Vector3d& point) const;

  // Bending energy sum_d w_d^T (-K) w_d (>= 0; 0 exactly for an affine warp).
  double bendingEnergy() const;

  const Eigen::MatrixX3d& centres() const { return centres_; }
  const Eigen::MatrixX3d& kernelWeights() const { return kernel_weights_; }  // #n by 3 (w)
  const Eigen::Matrix<double, 4, 3>& affine() const { return affine_; }       // rows: x, y, z, 1

 private:
  Eigen::MatrixX3d centres_;
  Eigen::MatrixX3d kernel_weights_;
  Eigen::Matrix<double, 4, 3> affine_ = Eigen::Matrix<double, 4, 3>::Zero();
};

// Leave-one-out diagnostics of one fit: how well each landmark is predicted by
// the spline through all the others (Rippa 1999: e_i = c_i / (L^-1)_ii).
struct TpsLeaveOneOut {
  std::vector<double> residuals;  // #n, |q_i - f^(-i)(p_i)| in target units
  std::vector<int> suspicious;    // indices of outliers among the residuals
};

class TpsFactorization {
 public:
  // centres: #n by 3 source landmark positions (n >= 4, not coplanar).
  // `names` (optional, #n) is only used in error messages.
  static Result<TpsFactorization> create(const Eigen::MatrixX3d& centres, const TpsOptions& options = {},
                                         const std::vector<std::string>& names = {});

  // targets: #n by 3 positions the centres map to.
  TpsWarp fit(const Eigen::MatrixX3d& targets) const;

  // Leave-one-out residuals for `targets`, and the landmarks that the others
  // cannot explain (residual > outlier_spacing_ratio x local landmark spacing),
  // found by backward elimination. Requires options.leave_one_out.
  TpsLeaveOneOut leaveOneOut(const Eigen::MatrixX3d& targets) const;

  // Bending-energy matrix B (#n by #n, symmetric positive semidefinite, zero
  // on affine maps: B [centres 1] = 0): the spline fitted to targets Y has
  // kernel weights -B Y and, without regularisation, bending energy
  // tr(Y^T B Y). Dense and O(n^3) (~6 ms at n = 465), so computed on request
  // and kept by the caller; used to slide centres along a surface.
  // kSingle: the inner inverse is formed in float where that is accurate (see
  // tps.cpp), ~2x faster, entries good to single precision (relative ~1e-7 for
  // regularised dense maps, so B [centres 1] is ~1e-7 |B|, not 0): for callers
  // whose products run in float anyway.
  enum class BendingPrecision { kDouble, kSingle };
  Eigen::MatrixXd bendingEnergyMatrix(BendingPrecision precision = BendingPrecision::kDouble) const;

  int size() const;
  const Eigen::MatrixX3d& centres() const;
  std::size_t memoryBytes() const;

  struct Data;

 private:
  std::shared_ptr<const Data> data_;  // immutable, shared by copies
};

// The geometric checks of TpsFactorization::create without factorising: at
// least 4 finite centres, no two at the same position (named), not (nearly)
// coplanar. Use it to validate a landmark set that is not itself factorised.
Status checkTpsCentres(const Eigen::MatrixX3d& centres, const TpsOptions& options = {},
                       const std::vector<std::string>& names = {});

// One-off convenience: factorise and fit.
Result<TpsWarp> fitTps(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target, const TpsOptions& options = {});

}  // namespace core
