// Radial basis function interpolation from precomputed distances (papers 002
// eq. 2.1-2.5 and 5.1): values q_j at centres m_j are interpolated by
//   f(x) = sum_k w_k phi(d(x, m_k)) + p(x),
// where d is any distance (Euclidean, geodesic, hybrid) given as matrices, so
// the same code serves every distance of core/retarget/retarget.h.
//
// Fit once, apply many: RbfFactorization depends only on the centre-to-centre
// distances (and options), is immutable and shared by copies; solve() takes
// any number of right-hand sides at once (#centres by 3*#frames for a whole
// clip), and evaluation of all points for all columns is one matrix product
// basis(point distances) * weights.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"

namespace core {

enum class RbfKernel {
  kGaussian,      // exp(-r / gamma): paper 002 eq. 5.1 exactly as written (an exponential in r, not r^2)
  kMultiquadric,  // sqrt(r^2 + gamma^2)
  kThinPlate,     // r^2 log r (0 at r = 0)
  kLinear,        // r
};

enum class RbfPolynomial {
  kAuto,      // kGaussian: none; kMultiquadric, kLinear: constant; kThinPlate: affine when centre positions are given, else constant
  kNone,      // pure kernel sum
  kConstant,  // + c (one extra unknown per column; works with any distance, e.g. geodesic)
  kAffine,    // + a.x + c (four extra unknowns; needs centre and point positions: Euclidean only in meaning)
};

struct RbfOptions {
  RbfKernel kernel = RbfKernel::kGaussian;  // phi
  // Shape parameter, distance units: kGaussian's decay length, kMultiquadric's offset (> 0 there; unused otherwise).
  double gamma = 1.0;
  RbfPolynomial polynomial = RbfPolynomial::kAuto;  // the polynomial term
  // Per-centre stiffness on the paper's 1-9 scale (1: interpolated exactly, 9: stiffest); empty = all 1.
  std::vector<double> stiffness;
  // Stiffness s adds +-stiffness_step * (s - 1) * (mean |phi| of the centre kernel matrix) to the centre's diagonal.
  double stiffness_step = 0.05;
  // The system is singular when its smallest singular value is below this fraction of the largest.
  double singular_tolerance = 1e-13;
};

// phi(r) of `kernel` with shape parameter `gamma`; +Inf distance gives 0 for kGaussian.
double rbfKernelValue(RbfKernel kernel, double gamma, double r);

// Stable lower_snake names ("gaussian", "multiquadric", "thin_plate", "linear").
const char* rbfKernelName(RbfKernel kernel);

class RbfFactorization {
 public:
  // centre_distances: #M by #M, symmetric, finite, >= 0, zero diagonal (model
  // units). centre_positions: #M by 3, needed only for an affine polynomial
  // (may have 0 rows otherwise). Errors: bad shapes, non-finite or negative
  // distances, stiffness outside [1, 9], gamma <= 0 where needed, too few
  // centres for the polynomial, a singular system (duplicate centres).
  static Result<RbfFactorization> create(const Eigen::MatrixXd& centre_distances,
                                         const Eigen::MatrixX3d& centre_positions, const RbfOptions& options);

  // values: #M by #C (e.g. marker displacements, #M by 3*#frames).
  // Returns #(M + polynomial terms) by #C weights: kernel weights first, then
  // the polynomial coefficients (constant; or x, y, z, constant).
  Eigen::MatrixXd solve(const Eigen::MatrixXd& values) const;

  // Evaluation basis of #P points: #P by #(M + polynomial terms), from the
  // #P by #M point-to-centre distances and (affine only) #P by 3 positions.
  // NaN, negative, or +Inf distances (except +Inf with kGaussian, whose
  // influence is then 0) are an Error naming the point and centre.
  Result<Eigen::MatrixXd> basis(const Eigen::MatrixXd& point_distances, const Eigen::MatrixX3d& point_positions) const;

  // basis * weights: #P by #C values, the one matrix product of evaluation.
  static Eigen::MatrixXd evaluate(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& weights) { return basis * weights; }

  int centreCount() const;
  int polynomialTerms() const;            // 0, 1 or 4
  RbfPolynomial polynomial() const;       // resolved (never kAuto)
  const RbfOptions& options() const;
  // The centres' own basis (#M by #(M + terms)) without regularisation: basis
  // * solve(values) reproduces `values` exactly when every stiffness is 1.
  const Eigen::MatrixXd& centreBasis() const;
  double conditionEstimate() const;       // largest / smallest singular value of the system

  struct Data;

 private:
  std::shared_ptr<const Data> data_;  // immutable, shared by copies
};

}  // namespace core
