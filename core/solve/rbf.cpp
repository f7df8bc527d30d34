// RBF interpolation from distance matrices.
// Papers: 002 (Ramos Carretero 2019) eq. 2.1-2.5 and 5.1 (the Gaussian written
// as exp(-r/gamma)); Hardy 1971 (multiquadric); Duchon 1977 / Bookstein 1989
// (thin-plate r^2 log r and its affine term); Micchelli 1986 (conditionally
// positive definite kernels need the polynomial term).
//
// The system is the usual saddle point
//   [K + Lambda  P] [w]   [q]
//   [P^T         0] [a] = [0],
// K_jk = phi(d(m_j, m_k)), P the polynomial basis at the centres, Lambda the
// stiffness diagonal. It is factorised once (LU) and back-substitutes all
// right-hand side columns together.
#include "core/solve/rbf.h"

#include <cmath>
#include <limits>

#include <Eigen/LU>
#include <Eigen/SVD>

namespace core {

struct RbfFactorization::Data {
  RbfOptions options;
  RbfPolynomial polynomial = RbfPolynomial::kNone;
  int centres = 0;
  int terms = 0;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu;
  Eigen::MatrixXd centre_basis;  // #M by #(M + terms), no regularisation
  double condition = 0.0;
};

double rbfKernelValue(RbfKernel kernel, double gamma, double r) {
  switch (kernel) {
    case RbfKernel::kGaussian: return std::exp(-r / gamma);
    case RbfKernel::kMultiquadric: return std::sqrt(r * r + gamma * gamma);
    case RbfKernel::kThinPlate: return r > 0.0 ? r * r * std::log(r) : 0.0;
    case RbfKernel::kLinear: return r;
  }
  return 0.0;
}

const char* rbfKernelName(RbfKernel kernel) {
  switch (kernel) {
    case RbfKernel::kGaussian: return "gaussian";
    case RbfKernel::kMultiquadric: return "multiquadric";
    case RbfKernel::kThinPlate: return "thin_plate";
    case RbfKernel::kLinear: return "linear";
  }
  return "unknown";
}

namespace {

int termCount(RbfPolynomial p) {
  return p == RbfPolynomial::kAffine ? 4 : p == RbfPolynomial::kConstant ? 1 : 0;
}

RbfPolynomial resolvePolynomial(const RbfOptions& options, bool have_positions) {
  if (options.polynomial != RbfPolynomial::kAuto) return options.polynomial;
  switch (options.kernel) {
    case RbfKernel::kGaussian: return RbfPolynomial::kNone;
    case RbfKernel::kMultiquadric:
    case RbfKernel::kLinear: return RbfPolynomial::kConstant;
    case RbfKernel::kThinPlate: return have_positions ? RbfPolynomial::kAffine : RbfPolynomial::kConstant;
  }
  return RbfPolynomial::kNone;
}

// Sign of the regularisation that keeps the kernel block away from singular:
// + for (conditionally) positive definite kernels, - for those whose negation is.
double regularisationSign(RbfKernel kernel) {
  return kernel == RbfKernel::kMultiquadric || kernel == RbfKernel::kLinear ? -1.0 : 1.0;
}

bool needsGamma(RbfKernel kernel) { return kernel == RbfKernel::kGaussian || kernel == RbfKernel::kMultiquadric; }

// Kernel of a distance block plus the polynomial columns.
Eigen::MatrixXd assembleBasis(const Eigen::MatrixXd& distances, const Eigen::MatrixX3d& positions, const RbfOptions& options,
                              int terms) {
  const Eigen::Index rows = distances.rows(), m = distances.cols();
  Eigen::MatrixXd b(rows, m + terms);
  b.leftCols(m) = distances.unaryExpr([&](double r) { return rbfKernelValue(options.kernel, options.gamma, r); });
  if (terms == 1) b.col(m).setOnes();
  if (terms == 4) {
    b.middleCols(m, 3) = positions;
    b.col(m + 3).setOnes();
  }
  return b;
}

Error invalid(const std::string& message) { return makeError(ErrorCode::kInvalidArgument, "rbf: " + message); }

}  // namespace

Result<RbfFactorization> RbfFactorization::create(const Eigen::MatrixXd& centre_distances,
                                                  const Eigen::MatrixX3d& centre_positions, const RbfOptions& options) {
  const Eigen::Index m = centre_distances.rows();
  if (m < 1 || centre_distances.cols() != m) {
    return invalid("centre distances must be square and non-empty, got " + std::to_string(m) + " by " +
                   std::to_string(centre_distances.cols()));
  }
  if (needsGamma(options.kernel) && !(options.gamma > 0.0 && std::isfinite(options.gamma))) {
    return invalid(std::string("gamma must be > 0 for the ") + rbfKernelName(options.kernel) + " kernel, got " +
                   std::to_string(options.gamma));
  }
  for (Eigen::Index j = 0; j < m; ++j) {
    for (Eigen::Index k = 0; k < m; ++k) {
      const double d = centre_distances(j, k);
      if (!std::isfinite(d) || d < 0.0) {
        return makeError(ErrorCode::kInvalidArgument, "rbf: distance between centres " + std::to_string(j) + " and " +
                                                          std::to_string(k) + " is " + std::to_string(d) +
                                                          " (must be finite and >= 0)");
      }
    }
  }
  if (!options.stiffness.empty() && static_cast<Eigen::Index>(options.stiffness.size()) != m) {
    return invalid(std::to_string(options.stiffness.size()) + " stiffness values for " + std::to_string(m) + " centres");
  }
  for (std::size_t i = 0; i < options.stiffness.size(); ++i) {
    const double s = options.stiffness[i];
    if (!(s >= 1.0 && s <= 9.0)) {
      return invalid("stiffness of centre " + std::to_string(i) + " is " + std::to_string(s) + " (the scale is 1-9)");
    }
  }
  if (!(options.stiffness_step >= 0.0 && std::isfinite(options.stiffness_step))) {
    return invalid("stiffness_step must be finite and >= 0");
  }
  const bool have_positions = centre_positions.rows() == m;
  if (centre_positions.rows() != 0 && !have_positions) {
    return invalid(std::to_string(centre_positions.rows()) + " centre positions for " + std::to_string(m) + " centres");
  }
  if (have_positions && !centre_positions.allFinite()) return invalid("centre positions are not finite");

  auto data = std::make_shared<Data>();
  data->options = options;
  data->polynomial = resolvePolynomial(options, have_positions);
  data->options.polynomial = data->polynomial;
  if (data->polynomial == RbfPolynomial::kAffine && !have_positions) {
    return invalid("an affine polynomial needs the centre positions (use a constant one with geodesic distances)");
  }
  data->terms = termCount(data->polynomial);
  data->centres = static_cast<int>(m);
  if (m < data->terms) {
    return makeError(ErrorCode::kIllConditioned, "rbf: " + std::to_string(m) + " centres cannot determine " +
                                                     std::to_string(data->terms) + " polynomial terms");
  }
  data->centre_basis = assembleBasis(centre_distances, centre_positions, options, data->terms);

  const Eigen::Index n = m + data->terms;
  Eigen::MatrixXd system = Eigen::MatrixXd::Zero(n, n);
  system.topRows(m) = data->centre_basis;
  system.bottomLeftCorner(data->terms, m) = data->centre_basis.rightCols(data->terms).transpose();
  if (!options.stiffness.empty()) {
    const double scale = data->centre_basis.leftCols(m).cwiseAbs().mean();
    const double step = regularisationSign(options.kernel) * options.stiffness_step * (scale > 0.0 ? scale : 1.0);
    for (Eigen::Index i = 0; i < m; ++i) system(i, i) += step * (options.stiffness[static_cast<std::size_t>(i)] - 1.0);
  }
  if (!system.allFinite()) return invalid("the kernel matrix is not finite (gamma too small for these distances?)");

  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(system);
  const auto& sv = svd.singularValues();
  const double smax = sv(0), smin = sv(sv.size() - 1);
  data->condition = smin > 0.0 ? smax / smin : std::numeric_limits<double>::infinity();
  if (!(smin > options.singular_tolerance * smax)) {
    return makeError(ErrorCode::kIllConditioned,
                     "rbf: the interpolation system of " + std::to_string(m) + " centres is singular (condition " +
                         std::to_string(data->condition) + "): duplicate centres, or centres on a plane/line with an "
                         "affine polynomial?");
  }
  data->lu.compute(system);
  RbfFactorization f;
  f.data_ = std::move(data);
  return f;
}

Eigen::MatrixXd RbfFactorization::solve(const Eigen::MatrixXd& values) const {
  assert(values.rows() == data_->centres);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(data_->centres + data_->terms, values.cols());
  rhs.topRows(data_->centres) = values;
  return data_->lu.solve(rhs);
}

Result<Eigen::MatrixXd> RbfFactorization::basis(const Eigen::MatrixXd& point_distances,
                                                const Eigen::MatrixX3d& point_positions) const {
  const Data& d = *data_;
  if (point_distances.cols() != d.centres) {
    return invalid("point distances have " + std::to_string(point_distances.cols()) + " columns for " +
                   std::to_string(d.centres) + " centres");
  }
  if (d.terms == 4 && point_positions.rows() != point_distances.rows()) {
    return invalid("an affine polynomial needs the " + std::to_string(point_distances.rows()) + " point positions");
  }
  if (d.terms == 4 && !point_positions.allFinite()) return invalid("point positions are not finite");
  const bool inf_ok = d.options.kernel == RbfKernel::kGaussian;
  for (Eigen::Index k = 0; k < point_distances.cols(); ++k) {
    for (Eigen::Index p = 0; p < point_distances.rows(); ++p) {
      const double r = point_distances(p, k);
      if (!(r >= 0.0) || (std::isinf(r) && !inf_ok)) {
        return makeError(ErrorCode::kInvalidArgument, "rbf: distance from point " + std::to_string(p) + " to centre " +
                                                          std::to_string(k) + " is " + std::to_string(r) +
                                                          (std::isinf(r) ? " (unreachable; only the gaussian kernel "
                                                                           "gives such points no influence)"
                                                                         : " (must be >= 0)"));
      }
    }
  }
  return assembleBasis(point_distances, point_positions, d.options, d.terms);
}

int RbfFactorization::centreCount() const { return data_->centres; }
int RbfFactorization::polynomialTerms() const { return data_->terms; }
RbfPolynomial RbfFactorization::polynomial() const { return data_->polynomial; }
const RbfOptions& RbfFactorization::options() const { return data_->options; }
const Eigen::MatrixXd& RbfFactorization::centreBasis() const { return data_->centre_basis; }
double RbfFactorization::conditionEstimate() const { return data_->condition; }

}  // namespace core
