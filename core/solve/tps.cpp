// Thin-plate spline in 3D with kernel U(r) = r.
//   Bookstein, "Principal warps: thin-plate splines and the decomposition of
//   deformations", PAMI 1989; papers 004 eq. 1-2 and 000 ch. 4.7.1.
//   Leave-one-out residuals: Rippa, "An algorithm for selecting a good value for
//   the parameter c in radial basis function interpolation", 1999.
//
// Solve, in coordinates normalised by the centres' centroid and RMS radius:
//   (K - lambda I) w + P a = q,  P^T w = 0,   P = [x y z 1].
// With the QR of P = [Q1 Q2][R; 0], w = Q2 c lies in the null space of P^T, and
//   M c = -Q2^T q,   M = Q2^T (lambda I - K) Q2,
// where M is symmetric positive definite because -U(r) = -r is conditionally
// positive definite of order 1 in R^3. So one Cholesky factorisation of M per
// centre set serves every right-hand side; a = R^-1 Q1^T (q - (K - lambda I) w).
#include "core/solve/tps.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <sstream>

#include "core/geometry/mesh.h"
#include "core/base/parallel.h"
#include "core/base/vector_clones.h"

namespace core {

namespace {

std::string landmarkLabel(const std::vector<std::string>& names, Eigen::Index i) {
  if (static_cast<std::size_t>(i) < names.size()) return "'" + names[static_cast<std::size_t>(i)] + "'";
  return "#" + std::to_string(i);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const std::size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  double m = v[mid];
  if (v.size() % 2 == 0) {
    m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return m;
}

}  // namespace

// ---------------------------------------------------------------------------
// TpsWarp

TpsWarp::TpsWarp(Eigen::MatrixX3d centres, Eigen::MatrixX3d kernel_weights, Eigen::Matrix<double, 4, 3> affine)
    : centres_(std::move(centres)), kernel_weights_(std::move(kernel_weights)), affine_(affine) {}

namespace {

// out.row(p) = sum_i |points.row(p) - centres.row(i)| * weights.row(i) for p
// in [begin, end). Points in blocks, centres outside, points inside: the inner
// loop has independent outputs and vectorises, while each point still sums
// its centres in order 0..n-1 (results do not depend on blocking or threads).
// Hot loops are compiled for AVX2 and baseline x86-64 (core/base/vector_clones.h;
// ~1.9x on TPS apply); each lane is one point summing its centres in the same
// order, so both clones give bit-identical results.

// Column pointers of a #n by 3 matrix (column-major: each column contiguous).
struct Columns {
  explicit Columns(const Eigen::MatrixX3d& m) : x(m.col(0).data()), y(m.col(1).data()), z(m.col(2).data()) {}
  const double* x;
  const double* y;
  const double* z;
};

// Points [b, b + m) into the block's coordinate arrays.
inline void loadBlock(const Eigen::MatrixX3d& points, std::ptrdiff_t b, std::ptrdiff_t m, double* x, double* y,
                      double* z) {
  for (std::ptrdiff_t j = 0; j < m; ++j) {
    x[j] = points(b + j, 0);
    y[j] = points(b + j, 1);
    z[j] = points(b + j, 2);
  }
}

RIGPORT_VECTOR_CLONES
void kernelSums(const Eigen::MatrixX3d& centres, const Eigen::MatrixX3d& weights, const Eigen::MatrixX3d& points,
                std::ptrdiff_t begin, std::ptrdiff_t end, Eigen::MatrixX3d& out) {
  const Eigen::Index n = centres.rows();
  const Columns c(centres), w(weights);
  constexpr std::ptrdiff_t kBlock = 64;
  alignas(64) double x[kBlock], y[kBlock], z[kBlock], sx[kBlock], sy[kBlock], sz[kBlock];
  for (std::ptrdiff_t b = begin; b < end; b += kBlock) {
    const std::ptrdiff_t m = std::min(kBlock, end - b);
    loadBlock(points, b, m, x, y, z);
    for (std::ptrdiff_t j = 0; j < m; ++j) sx[j] = sy[j] = sz[j] = 0.0;
    for (Eigen::Index i = 0; i < n; ++i) {
      const double px = c.x[i], py = c.y[i], pz = c.z[i], ax = w.x[i], ay = w.y[i], az = w.z[i];
      for (std::ptrdiff_t j = 0; j < m; ++j) {
        const double dx = x[j] - px, dy = y[j] - py, dz = z[j] - pz;
        const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
        sx[j] += ax * r;
        sy[j] += ay * r;
        sz[j] += az * r;
      }
    }
    for (std::ptrdiff_t j = 0; j < m; ++j) {
      out(b + j, 0) = sx[j];
      out(b + j, 1) = sy[j];
      out(b + j, 2) = sz[j];
    }
  }
}

// out[p] = sum_i weights.row(i)^T (points.row(p) - centres.row(i)) / r_i,
// the kernel part of the Jacobian (d/dx (w |x - p|) = w (x - p)^T / |x - p|),
// blocked like kernelSums: the nine sums vectorise over the block.
RIGPORT_VECTOR_CLONES
void kernelGradientSums(const Eigen::MatrixX3d& centres, const Eigen::MatrixX3d& weights,
                        const Eigen::MatrixX3d& points, std::ptrdiff_t begin, std::ptrdiff_t end,
                        std::vector<Eigen::Matrix3d>& out) {
  const Eigen::Index n = centres.rows();
  const Columns c(centres), w(weights);
  constexpr std::ptrdiff_t kBlock = 32;
  alignas(64) double x[kBlock], y[kBlock], z[kBlock];
  alignas(64) double s[9][kBlock];
  for (std::ptrdiff_t b = begin; b < end; b += kBlock) {
    const std::ptrdiff_t m = std::min(kBlock, end - b);
    loadBlock(points, b, m, x, y, z);
    for (auto& row : s) std::fill(row, row + m, 0.0);
    for (Eigen::Index i = 0; i < n; ++i) {
      const double px = c.x[i], py = c.y[i], pz = c.z[i], ax = w.x[i], ay = w.y[i], az = w.z[i];
      for (std::ptrdiff_t j = 0; j < m; ++j) {
        const double dx = x[j] - px, dy = y[j] - py, dz = z[j] - pz;
        // The cone tip at a centre has no derivative and contributes
        // nothing: d = 0 there, and the tiny addend keeps 0 * inv finite
        // (it vanishes in any r^2 above ~1e-284; no branch, so the loop
        // vectorises).
        const double inv = 1.0 / std::sqrt(dx * dx + dy * dy + dz * dz + 1e-300);
        const double ux = dx * inv, uy = dy * inv, uz = dz * inv;
        s[0][j] += ax * ux;
        s[1][j] += ax * uy;
        s[2][j] += ax * uz;
        s[3][j] += ay * ux;
        s[4][j] += ay * uy;
        s[5][j] += ay * uz;
        s[6][j] += az * ux;
        s[7][j] += az * uy;
        s[8][j] += az * uz;
      }
    }
    for (std::ptrdiff_t j = 0; j < m; ++j) {
      Eigen::Matrix3d& jac = out[static_cast<std::size_t>(b + j)];
      for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) jac(row, col) = s[3 * row + col][j];
      }
    }
  }
}

}  // namespace

Eigen::MatrixX3d TpsWarp::apply(const Eigen::MatrixX3d& points) const {
  Eigen::MatrixX3d out(points.rows(), 3);
  parallelFor(points.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    kernelSums(centres_, kernel_weights_, points, begin, end, out);
    for (std::ptrdiff_t p = begin; p < end; ++p) {
      const double x = points(p, 0), y = points(p, 1), z = points(p, 2);
      for (int c = 0; c < 3; ++c) {
        out(p, c) = out(p, c) + affine_(0, c) * x + affine_(1, c) * y + affine_(2, c) * z + affine_(3, c);
      }
    }
  }, 64);
  return out;
}

Eigen::Vector3d TpsWarp::apply(const Eigen::Vector3d& point) const {
  Eigen::Vector3d out = affine_.topRows<3>().transpose() * point + affine_.row(3).transpose();
  for (Eigen::Index i = 0; i < centres_.rows(); ++i) {
    out += kernel_weights_.row(i).transpose() * (point - centres_.row(i).transpose()).norm();
  }
  return out;
}

Eigen::Matrix3d TpsWarp::jacobian(const Eigen::Vector3d& point) const {
  // d/dx (w_i |x - p_i|) = w_i (x - p_i)^T / |x - p_i|; the cone tip at a centre
  // has no derivative and contributes nothing there.
  Eigen::Matrix3d j = affine_.topRows<3>().transpose();
  for (Eigen::Index i = 0; i < centres_.rows(); ++i) {
    const Eigen::Vector3d d = point - centres_.row(i).transpose();
    const double r = d.norm();
    if (r > 0.0) j += kernel_weights_.row(i).transpose() * (d.transpose() / r);
  }
  return j;
}

std::vector<Eigen::Matrix3d> TpsWarp::jacobians(const Eigen::MatrixX3d& points) const {
  std::vector<Eigen::Matrix3d> out(static_cast<std::size_t>(points.rows()));
  parallelFor(points.rows(), [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    kernelGradientSums(centres_, kernel_weights_, points, begin, end, out);
    for (std::ptrdiff_t p = begin; p < end; ++p) {
      out[static_cast<std::size_t>(p)] += affine_.topRows<3>().transpose();
    }
  }, 64);
  return out;
}

double TpsWarp::bendingEnergy() const {
  double energy = 0.0;
  const Eigen::Index n = centres_.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = i + 1; j < n; ++j) {
      const double r = (centres_.row(i) - centres_.row(j)).norm();
      energy -= 2.0 * r * kernel_weights_.row(i).dot(kernel_weights_.row(j));
    }
  }
  return std::max(0.0, energy);  // rounding can leave a tiny negative for affine warps
}

// ---------------------------------------------------------------------------
// TpsFactorization

struct TpsFactorization::Data {
  Eigen::MatrixX3d centres;          // #n by 3, model units
  Eigen::MatrixX3d centres_normal;   // #n by 3, normalised: (p - centroid) / scale
  Eigen::RowVector3d centroid;
  double scale = 1.0;
  double lambda_normal = 0.0;        // regularisation in normalised units
  Eigen::HouseholderQR<Eigen::MatrixXd> qr;  // of P (#n by 4)
  Eigen::LLT<Eigen::MatrixXd> llt;   // of M ((n-4) by (n-4))
  Eigen::VectorXd loo_diagonal;      // diag of the top-left block of L^-1 (empty if not computed)
  double outlier_spacing_ratio = 1.0;
  TpsOptions options;
};

namespace {

// The 4 reflections of the QR of P as one block, Q = H_0 H_1 H_2 H_3 =
// I - V T V^T (compact WY form, T upper triangular), so that conjugating a
// #n by #n matrix by Q is a few rank-4 products instead of 8 passes of
// single reflections (0.5 against 1.0 ms at n = 465).
struct BlockReflector {
  Eigen::MatrixX4d v;
  Eigen::Matrix4d t = Eigen::Matrix4d::Zero();
};

BlockReflector blockReflector(const Eigen::HouseholderQR<Eigen::MatrixXd>& qr) {
  const Eigen::Index n = qr.matrixQR().rows();
  BlockReflector r;
  r.v = Eigen::MatrixX4d::Zero(n, 4);
  for (Eigen::Index i = 0; i < 4; ++i) {
    r.v(i, i) = 1.0;
    r.v.col(i).tail(n - i - 1) = qr.matrixQR().col(i).tail(n - i - 1);
    const double tau = qr.hCoeffs()(i);
    r.t(i, i) = tau;
    if (i > 0) {
      const Eigen::VectorXd vtv = r.v.leftCols(i).transpose() * r.v.col(i);
      const Eigen::VectorXd tv = r.t.topLeftCorner(i, i) * vtv;  // T is upper triangular
      r.t.col(i).head(i) = -tau * tv;
    }
  }
  return r;
}

// U^T A U for symmetric A with U = I - V T V^T: A - Y V^T - V Z^T, where
// Y = A V T and Z = Y - V (Y^T V) T. With T: Q^T A Q; with T^T: Q A Q^T.
void conjugateSymmetric(Eigen::MatrixXd& a, const Eigen::MatrixX4d& v, const Eigen::Matrix4d& t) {
  const Eigen::MatrixX4d y = (a * v) * t;
  const Eigen::Matrix4d ytv = y.transpose() * v;
  const Eigen::MatrixX4d z = y - v * (ytv * t);
  Eigen::Matrix<double, Eigen::Dynamic, 8> left(a.rows(), 8), right(a.rows(), 8);
  left << y, v;
  right << v, z;
  a.noalias() -= left * right.transpose();
}

// M^-1 (m by m) from M = L L^T: M^-1 = L^-T L^-1, both steps blocked so the
// zeros of the triangles are skipped (~2m^3/3 flops instead of ~2m^3 for a
// solve against the identity: 11 -> 5 ms at m = 461).
template <class Scalar>
Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic> inverseFromCholesky(
    const Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>& l) {
  using Matrix = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
  const Eigen::Index m = l.rows();
  constexpr Eigen::Index kBlock = 64;
  // X = L^-1, block column by block column: rows above the block are zero.
  Matrix x = Matrix::Zero(m, m);
  for (Eigen::Index c = 0; c < m; c += kBlock) {
    const Eigen::Index b = std::min(kBlock, m - c);
    x.block(c, c, b, b).setIdentity();
    l.bottomRightCorner(m - c, m - c).template triangularView<Eigen::Lower>().solveInPlace(x.block(c, c, m - c, b));
  }
  // M^-1 = X^T X, lower part of each block column: rows r >= c only need
  // X's rows >= c (X is lower triangular).
  Matrix inverse(m, m);
  for (Eigen::Index c = 0; c < m; c += kBlock) {
    const Eigen::Index b = std::min(kBlock, m - c);
    inverse.block(c, c, m - c, b).noalias() =
        x.bottomRightCorner(m - c, m - c).template triangularView<Eigen::Lower>().transpose() * x.block(c, c, m - c, b);
  }
  for (Eigen::Index j = 1; j < m; ++j) inverse.col(j).head(j) = inverse.row(j).head(j).transpose();
  return inverse;
}

// Q2 M^-1 Q2^T (#n by #n, n > 4): Q [0 0; 0 M^-1] Q^T. With kSingle, M^-1
// is formed in float (twice the SIMD lanes: ~6 -> ~3 ms at n = 465) when that
// keeps it accurate: its product with a fixed v must be within 1e-5
// (relative) of the double solve M^-1 v, else it is formed in double. The
// regularised dense maps' M is well conditioned (condition ~2e3 for the ICT
// rig's 465 centres: entries within 2e-7 of the double inverse).
Eigen::MatrixXd q2InverseQ2t(const TpsFactorization::Data& d, TpsFactorization::BendingPrecision precision) {
  const Eigen::Index n = d.centres.rows(), m = n - 4;
  Eigen::MatrixXd full = Eigen::MatrixXd::Zero(n, n);
  auto inverse = full.bottomRightCorner(m, m);
  bool formed = false;
  if (precision == TpsFactorization::BendingPrecision::kSingle) {
    inverse = inverseFromCholesky<float>(d.llt.matrixLLT().cast<float>()).cast<double>();
    Eigen::VectorXd v(m);
    for (Eigen::Index i = 0; i < m; ++i) v(i) = static_cast<double>((i * 7919) % 13) - 5.5;  // all frequencies
    const Eigen::VectorXd z = inverse * v;
    const Eigen::VectorXd back = d.llt.matrixL() * (d.llt.matrixU() * z);
    const Eigen::VectorXd error = d.llt.solve(back - v);  // z - M^-1 v, in double
    formed = error.norm() <= 1e-5 * z.norm();
  }
  if (!formed) inverse = inverseFromCholesky<double>(d.llt.matrixLLT());
  const BlockReflector q = blockReflector(d.qr);
  conjugateSymmetric(full, q.v, q.t.transpose());
  return full;
}

}  // namespace

Status checkTpsCentres(const Eigen::MatrixX3d& centres, const TpsOptions& options,
                       const std::vector<std::string>& names) {
  const Eigen::Index n = centres.rows();
  if (n < 4) {
    return makeError(ErrorCode::kInvalidLandmarks,
                     "thin-plate spline needs at least 4 landmarks, got " + std::to_string(n));
  }
  if (!centres.allFinite()) return makeError(ErrorCode::kInvalidLandmarks, "landmark positions are not finite");
  const Eigen::MatrixX3d centred = centres.rowwise() - centres.colwise().mean();
  if (!(centred.rowwise().squaredNorm().mean() > 0.0)) {
    return makeError(ErrorCode::kIllConditioned, "all landmarks are at the same position");
  }
  // Duplicates make K singular; name the pair rather than report a bad solve.
  const double dup = options.duplicate_tolerance * boundingBoxDiagonal(centres);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = i + 1; j < n; ++j) {
      if ((centres.row(i) - centres.row(j)).squaredNorm() <= dup * dup) {
        return makeError(ErrorCode::kIllConditioned, "landmarks " + landmarkLabel(names, i) + " and " +
                                                         landmarkLabel(names, j) + " are at the same position");
      }
    }
  }
  // Coplanar (or collinear) centres leave the affine part undetermined.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred.transpose() * centred);
  const Eigen::Vector3d ev = eig.eigenvalues().cwiseMax(0.0);  // ascending
  const double flatness = std::sqrt(ev(0) / ev(2));
  if (!(flatness >= options.min_flatness)) {
    std::ostringstream msg;
    msg << "landmarks are (nearly) coplanar: thinnest extent is " << flatness
        << " of the largest; at least 4 landmarks must span 3D";
    return makeError(ErrorCode::kIllConditioned, msg.str());
  }
  return Ok{};
}

Result<TpsFactorization> TpsFactorization::create(const Eigen::MatrixX3d& centres, const TpsOptions& options,
                                                  const std::vector<std::string>& names) {
  const Eigen::Index n = centres.rows();
  if (auto ok = checkTpsCentres(centres, options, names); !ok) return ok.error();
  if (!(options.regularization >= 0.0) || !std::isfinite(options.regularization)) {
    return makeError(ErrorCode::kInvalidArgument, "TPS regularization must be a finite value >= 0");
  }

  auto data = std::make_shared<Data>();
  data->centres = centres;
  data->outlier_spacing_ratio = options.outlier_spacing_ratio;
  data->options = options;
  data->centroid = centres.colwise().mean();
  const Eigen::MatrixX3d centred = centres.rowwise() - data->centroid;
  data->scale = std::sqrt(centred.rowwise().squaredNorm().mean());

  data->centres_normal = centred / data->scale;
  data->lambda_normal = options.regularization / data->scale;
  const Eigen::MatrixX3d& p = data->centres_normal;

  Eigen::MatrixXd P(n, 4);
  P.leftCols<3>() = p;
  P.col(3).setOnes();
  data->qr.compute(P);

  // B = lambda I - K, then M = Q2^T B Q2 via Q^T B Q. Reflection by
  // reflection, as always: the block form (conjugateSymmetric) would save
  // ~0.5 ms at n = 465 but round every fit differently, moving transfers by
  // up to ~0.5 mm through the sliding (no more accurate either way).
  Eigen::MatrixXd B(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    B(i, i) = data->lambda_normal;
    for (Eigen::Index j = i + 1; j < n; ++j) {
      const double r = (p.row(i) - p.row(j)).norm();
      B(i, j) = -r;
      B(j, i) = -r;
    }
  }
  const auto householder = data->qr.householderQ();
  B.applyOnTheLeft(householder.adjoint());
  B.applyOnTheRight(householder);
  const Eigen::MatrixXd M = B.bottomRightCorner(n - 4, n - 4);
  if (n > 4) {
    data->llt.compute(M);
    if (data->llt.info() != Eigen::Success) {
      return makeError(ErrorCode::kIllConditioned, "thin-plate spline system is singular for these landmarks");
    }
    const Eigen::VectorXd d = data->llt.matrixLLT().diagonal();  // L's diagonal
    const double rcond = (d.minCoeff() / d.maxCoeff());
    if (!(rcond * rcond > 1e-13)) {
      return makeError(ErrorCode::kIllConditioned,
                       "thin-plate spline system is ill-conditioned (near-duplicate landmarks?)");
    }
  }

  if (options.leave_one_out && n > 4) data->loo_diagonal = -q2InverseQ2t(*data, BendingPrecision::kDouble).diagonal();

  TpsFactorization f;
  f.data_ = std::move(data);
  return f;
}

Eigen::MatrixXd TpsFactorization::bendingEnergyMatrix(BendingPrecision precision) const {
  // Weights are w = -Q2 M^-1 Q2^T q in normalised units and w / s in model
  // units.
  const Data& d = *data_;
  if (d.centres.rows() <= 4) return Eigen::MatrixXd::Zero(d.centres.rows(), d.centres.rows());
  return q2InverseQ2t(d, precision) / d.scale;
}

int TpsFactorization::size() const { return static_cast<int>(data_->centres.rows()); }
const Eigen::MatrixX3d& TpsFactorization::centres() const { return data_->centres; }

std::size_t TpsFactorization::memoryBytes() const {
  const std::size_t n = static_cast<std::size_t>(data_->centres.rows());
  return sizeof(Data) + sizeof(double) * (2 * 3 * n + 5 * n + (n >= 4 ? (n - 4) * (n - 4) : 0) + n);
}

namespace {

// Normalised-coordinate weights for one right-hand side set.
void solveNormalised(const Eigen::HouseholderQR<Eigen::MatrixXd>& qr, const Eigen::LLT<Eigen::MatrixXd>& llt,
                     const Eigen::MatrixX3d& p, double lambda, const Eigen::MatrixX3d& q, Eigen::MatrixX3d& w,
                     Eigen::Matrix<double, 4, 3>& a) {
  const Eigen::Index n = p.rows();
  const auto householder = qr.householderQ();
  Eigen::MatrixX3d qtq = q;
  qtq.applyOnTheLeft(householder.adjoint());
  Eigen::MatrixX3d coeffs = Eigen::MatrixX3d::Zero(n, 3);
  if (n > 4) coeffs.bottomRows(n - 4) = llt.solve(-qtq.bottomRows(n - 4));
  w = coeffs;
  w.applyOnTheLeft(householder);  // w = Q [0; c] = Q2 c

  // residual r = q - (K - lambda I) w, then a = R^-1 Q1^T r.
  Eigen::MatrixX3d kw(n, 3);
  kernelSums(p, w, p, 0, n, kw);
  Eigen::MatrixX3d r = q + lambda * w - kw;
  r.applyOnTheLeft(householder.adjoint());
  const Eigen::Matrix4d R = qr.matrixQR().topLeftCorner<4, 4>().triangularView<Eigen::Upper>();
  a = R.triangularView<Eigen::Upper>().solve(r.topRows<4>());
}

}  // namespace

TpsWarp TpsFactorization::fit(const Eigen::MatrixX3d& targets) const {
  const Data& d = *data_;
  assert(targets.rows() == d.centres.rows());
  Eigen::MatrixX3d w;
  Eigen::Matrix<double, 4, 3> a;
  solveNormalised(d.qr, d.llt, d.centres_normal, d.lambda_normal, targets, w, a);
  // Back to model coordinates: |x^ - p^_i| = |x - p_i| / s and x^ = (x - c) / s.
  Eigen::Matrix<double, 4, 3> affine;
  affine.topRows<3>() = a.topRows<3>() / d.scale;
  affine.row(3) = a.row(3) - d.centroid * affine.topRows<3>();
  return TpsWarp(d.centres, w / d.scale, affine);
}

namespace {

// Residual of each landmark predicted by the spline through all the others.
std::vector<double> looResiduals(const TpsFactorization::Data& d, const Eigen::MatrixX3d& targets);

}  // namespace

TpsLeaveOneOut TpsFactorization::leaveOneOut(const Eigen::MatrixX3d& targets) const {
  const Data& d = *data_;
  TpsLeaveOneOut out;
  const Eigen::Index n = d.centres.rows();
  if (d.loo_diagonal.size() != n) return out;
  out.residuals = looResiduals(d, targets);

  // Local spacing of each target landmark: distance to its nearest neighbour,
  // but not below a quarter of the median spacing, so that two landmarks that
  // (nearly) coincide, like touching lip corners, do not make noise look large.
  std::vector<double> nearest(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < n; ++j) {
      if (j != i) nearest[static_cast<std::size_t>(i)] = std::min(nearest[static_cast<std::size_t>(i)], (targets.row(i) - targets.row(j)).norm());
    }
  }
  const double spacing_floor = 0.25 * median(nearest);
  for (double& s : nearest) s = std::max(s, spacing_floor);

  // Backward elimination: a swapped or mislabelled landmark drags its
  // neighbours' leave-one-out predictions too, so flag only the worst, drop it,
  // refit and look again. Stops when every remaining landmark is predicted
  // within `outlier_spacing_ratio` of its spacing, or too few would remain.
  std::vector<int> active(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) active[static_cast<std::size_t>(i)] = static_cast<int>(i);
  std::vector<double> residuals = out.residuals;
  const std::size_t min_active = std::max<std::size_t>(5, static_cast<std::size_t>(n) / 2);
  while (active.size() > min_active) {
    std::size_t worst = 0;
    double worst_ratio = -1.0;
    for (std::size_t k = 0; k < active.size(); ++k) {
      const double ratio = residuals[k] / nearest[static_cast<std::size_t>(active[k])];
      if (ratio > worst_ratio) {
        worst_ratio = ratio;
        worst = k;
      }
    }
    if (!(worst_ratio > d.outlier_spacing_ratio)) break;
    out.suspicious.push_back(active[worst]);
    active.erase(active.begin() + static_cast<std::ptrdiff_t>(worst));

    Eigen::MatrixX3d sub_centres(static_cast<Eigen::Index>(active.size()), 3);
    Eigen::MatrixX3d sub_targets(static_cast<Eigen::Index>(active.size()), 3);
    for (std::size_t k = 0; k < active.size(); ++k) {
      sub_centres.row(static_cast<Eigen::Index>(k)) = d.centres.row(active[k]);
      sub_targets.row(static_cast<Eigen::Index>(k)) = targets.row(active[k]);
    }
    TpsOptions opts = d.options;
    opts.leave_one_out = true;
    auto sub = TpsFactorization::create(sub_centres, opts);
    if (!sub) break;  // what remains is degenerate: keep what was found so far
    residuals = looResiduals(*sub->data_, sub_targets);
  }
  std::sort(out.suspicious.begin(), out.suspicious.end());
  return out;
}

namespace {

std::vector<double> looResiduals(const TpsFactorization::Data& d, const Eigen::MatrixX3d& targets) {
  Eigen::MatrixX3d w;
  Eigen::Matrix<double, 4, 3> a;
  solveNormalised(d.qr, d.llt, d.centres_normal, d.lambda_normal, targets, w, a);
  std::vector<double> residuals(static_cast<std::size_t>(d.centres.rows()));
  for (Eigen::Index i = 0; i < d.centres.rows(); ++i) {
    // e_i = x_i / (L^-1)_ii with x_i the (normalised) kernel weight of centre i.
    residuals[static_cast<std::size_t>(i)] = w.row(i).norm() / std::abs(d.loo_diagonal(i));
  }
  return residuals;
}

}  // namespace

Result<TpsWarp> fitTps(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target, const TpsOptions& options) {
  if (source.rows() != target.rows()) {
    return makeError(ErrorCode::kInvalidArgument, "TPS source and target landmark counts differ (" +
                                                      std::to_string(source.rows()) + " vs " +
                                                      std::to_string(target.rows()) + ")");
  }
  TpsOptions opts = options;
  opts.leave_one_out = false;
  auto f = TpsFactorization::create(source, opts);
  if (!f) return f.error();
  return f->fit(target);
}

}  // namespace core
