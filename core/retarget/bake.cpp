// The bake of retargetMocap's displacement field into morph targets.
// The displacement field X (#frames by 3#V) equals C Q^T, with C the
// solved weights in an orthonormal basis of the kernel columns (#frames by
// 3r, r <= #markers + terms) and Q orthonormal (#V by r). Its SVD is that of
// the small C, so rank selection never forms X; the kept modes are evaluated
// on the vertices with one (#V by #markers) x (#markers by 3 rank) product.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <Eigen/Eigenvalues>

#include "core/base/parallel.h"
#include "core/base/timing.h"
#include "core/retarget/retarget_stages.h"
#include "core/solve/rbf.h"

namespace core {

namespace {

// The bake of the displacement field into modes.
struct Modes {
  Eigen::MatrixXd coefficients;  // #K by 3*rank: RBF weights of each mode's x, y, z (already scaled)
  Eigen::MatrixXd weights;       // #frames by rank, max |w| = 1 per mode
  std::vector<double> singular_values;
  int rank = 0;
  double relative_error = 0.0, rms_error = 0.0, max_error_bound = 0.0;
  bool tolerance_met = true;
  Eigen::MatrixXd residual_coefficients;  // #K by 3*#frames (x block, y block, z block): for the measured max
};

// weights: #K by 3F solved RBF weights (column 3f + c); basis: #V by #K.
Modes compressModes(const Eigen::MatrixXd& weights, const Eigen::MatrixXd& basis, const BakeOptions& options,
                    bool keep_residual) {
  const Eigen::Index nk = weights.rows(), nf = weights.cols() / 3, nv = basis.rows();
  Modes out;
  // Orthonormal coordinates of the basis columns: G = Phi^T Phi = E L E^T,
  // Phi = Q L^1/2 E^T with Q orthonormal on the kept eigenvalues.
  const Eigen::MatrixXd gram = basis.transpose() * basis;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ge(gram);
  const Eigen::VectorXd lambda = ge.eigenvalues();
  const double lmax = lambda.maxCoeff();
  std::vector<Eigen::Index> kept;
  for (Eigen::Index i = 0; i < nk; ++i) {
    if (lambda(i) > 1e-12 * lmax && lmax > 0.0) kept.push_back(i);
  }
  const Eigen::Index r0 = static_cast<Eigen::Index>(kept.size());
  Eigen::MatrixXd t(nk, r0), t_inv(nk, r0);  // E L^1/2 and E L^-1/2
  for (Eigen::Index j = 0; j < r0; ++j) {
    const Eigen::Index i = kept[static_cast<std::size_t>(j)];
    t.col(j) = ge.eigenvectors().col(i) * std::sqrt(lambda(i));
    t_inv.col(j) = ge.eigenvectors().col(i) / std::sqrt(lambda(i));
  }
  // C = [W_x^T T, W_y^T T, W_z^T T]: #F by 3 r0.
  Eigen::MatrixXd c(nf, 3 * r0);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>> wk(weights.data() + k * nk, nk, nf,
                                                                        Eigen::OuterStride<>(3 * nk));
    c.middleCols(k * r0, r0).noalias() = wk.transpose() * t;
  }
  const Eigen::MatrixXd h = c.transpose() * c;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> he(h);
  const Eigen::Index n = h.rows();
  Eigen::VectorXd sigma2(n);
  Eigen::MatrixXd v(n, n);
  for (Eigen::Index j = 0; j < n; ++j) {  // descending
    sigma2(j) = std::max(0.0, he.eigenvalues()(n - 1 - j));
    v.col(j) = he.eigenvectors().col(n - 1 - j);
  }
  const Eigen::MatrixXd y = c * v;  // #F by n: U S
  const double total = sigma2.sum();
  for (Eigen::Index j = 0; j < std::min<Eigen::Index>(n, 2 * options.max_rank); ++j) out.singular_values.push_back(std::sqrt(sigma2(j)));

  // Rank selection.
  const Eigen::Index cap = std::min<Eigen::Index>({n, nf, static_cast<Eigen::Index>(std::max(1, options.max_rank))});
  Eigen::VectorXd tail(n + 1);  // tail(r) = sum_{j >= r} sigma2
  tail(n) = 0.0;
  for (Eigen::Index j = n - 1; j >= 0; --j) tail(j) = tail(j + 1) + sigma2(j);
  const double q_max = (basis * t_inv).rowwise().norm().maxCoeff();
  Eigen::VectorXd frame_residual2 = c.rowwise().squaredNorm();  // ||C_perp(f)||^2 at rank 0
  auto bound = [&](const Eigen::VectorXd& fr2) { return q_max * std::sqrt(std::max(0.0, fr2.maxCoeff())); };
  Eigen::Index rank = 0;
  if (total > 0.0) {
    rank = cap;
    for (Eigen::Index r = 0; r <= cap; ++r) {
      if (r > 0) frame_residual2 -= y.col(r - 1).cwiseAbs2();
      const bool met = options.metric == BakeError::kRelativeFrobenius ? std::sqrt(tail(r) / total) <= options.tolerance
                                                                       : bound(frame_residual2) <= options.tolerance;
      if (met) {
        rank = r;
        break;
      }
    }
    // frame_residual2 now matches `rank` (or cap when the tolerance was missed).
  }
  out.tolerance_met = total == 0.0 ||
                      (options.metric == BakeError::kRelativeFrobenius ? std::sqrt(tail(rank) / total) <= options.tolerance
                                                                       : bound(frame_residual2) <= options.tolerance);
  out.relative_error = total > 0.0 ? std::sqrt(tail(rank) / total) : 0.0;
  out.rms_error = std::sqrt(tail(rank) / static_cast<double>(std::max<Eigen::Index>(1, nv * nf)));
  out.max_error_bound = bound(frame_residual2);
  out.rank = static_cast<int>(std::max<Eigen::Index>(rank, 1));  // at least one (zero) target for a motionless clip

  out.coefficients = Eigen::MatrixXd::Zero(nk, 3 * out.rank);
  out.weights = Eigen::MatrixXd::Zero(nf, out.rank);
  for (Eigen::Index j = 0; j < rank; ++j) {
    const double s = std::sqrt(sigma2(j));
    if (s <= 0.0) continue;
    Eigen::Index fmax = 0;
    y.col(j).cwiseAbs().maxCoeff(&fmax);
    const double peak = y(fmax, j);  // signed: the peak weight is +1
    out.weights.col(j) = y.col(j) / peak;
    for (int k = 0; k < 3; ++k) out.coefficients.col(3 * j + k) = peak * (t_inv * v.block(k * r0, j, r0, 1));
  }
  if (keep_residual) {
    const Eigen::MatrixXd c_perp = c - y.leftCols(rank) * v.leftCols(rank).transpose();  // #F by 3 r0
    out.residual_coefficients.resize(nk, 3 * nf);
    for (int k = 0; k < 3; ++k) out.residual_coefficients.middleCols(k * nf, nf) = t_inv * c_perp.middleCols(k * r0, r0).transpose();
  }
  return out;
}

// Max over vertices and frames of the residual displacement's length.
double measureMaxError(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& residual_coefficients) {
  const Eigen::Index nv = basis.rows(), nf = residual_coefficients.cols() / 3;
  constexpr Eigen::Index kChunk = 256;
  const Eigen::Index chunks = (nv + kChunk - 1) / kChunk;
  std::vector<double> chunk_max(static_cast<std::size_t>(chunks), 0.0);
  parallelFor(chunks, [&](std::ptrdiff_t begin, std::ptrdiff_t end) {
    for (std::ptrdiff_t ch = begin; ch < end; ++ch) {
      const Eigen::Index v0 = ch * kChunk, rows = std::min(kChunk, nv - v0);
      const Eigen::MatrixXd e = basis.middleRows(v0, rows) * residual_coefficients;  // rows by 3F
      const Eigen::MatrixXd len2 = e.leftCols(nf).cwiseAbs2() + e.middleCols(nf, nf).cwiseAbs2() + e.rightCols(nf).cwiseAbs2();
      chunk_max[static_cast<std::size_t>(ch)] = std::sqrt(len2.maxCoeff());
    }
  }, 1);
  return chunks > 0 ? *std::max_element(chunk_max.begin(), chunk_max.end()) : 0.0;
}

}  // namespace

// Exact: one morph target per frame, one-hot weights.
BakedMotion bakeFrames(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& weights) {
  const int nf = static_cast<int>(weights.cols() / 3);
  BakedMotion out;
  auto t0 = Clock::now();
  const Eigen::MatrixXd deltas = RbfFactorization::evaluate(basis, weights);  // #V by 3F
  out.evaluate_ms = msSince(t0);
  t0 = Clock::now();
  for (int f = 0; f < nf; ++f) {
    MorphTarget target;
    target.name = "frame_" + std::to_string(f);
    target.position_deltas = deltas.middleCols(3 * f, 3);
    out.targets.push_back(std::move(target));
  }
  out.frame_weights = Eigen::MatrixXd::Identity(nf, nf);
  out.report.exact = true;
  out.report.rank = nf;
  out.report.max_error_measured = true;
  out.bake_ms = msSince(t0);
  return out;
}

// Compressed: the leading modes of the displacement field (compressModes).
BakedMotion bakeModes(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& weights, const BakeOptions& bake) {
  BakedMotion out;
  auto t0 = Clock::now();
  const Modes modes = compressModes(weights, basis, bake, bake.measure_max_error);
  out.bake_ms = msSince(t0);
  t0 = Clock::now();
  const Eigen::MatrixXd deltas = RbfFactorization::evaluate(basis, modes.coefficients);  // #V by 3 rank
  if (bake.measure_max_error) {
    out.report.max_error = measureMaxError(basis, modes.residual_coefficients);
    out.report.max_error_measured = true;
  } else {
    out.report.max_error = modes.max_error_bound;
  }
  out.evaluate_ms = msSince(t0);
  t0 = Clock::now();
  char name[32];
  for (int j = 0; j < modes.rank; ++j) {
    std::snprintf(name, sizeof(name), "mode_%02d", j);
    MorphTarget target;
    target.name = name;
    target.position_deltas = deltas.middleCols(3 * j, 3);
    out.targets.push_back(std::move(target));
  }
  out.frame_weights = modes.weights;
  out.report.rank = modes.rank;
  out.report.tolerance_met = modes.tolerance_met;
  out.report.relative_error = modes.relative_error;
  out.report.rms_error = modes.rms_error;
  out.report.singular_values = modes.singular_values;
  out.bake_ms += msSince(t0);
  return out;
}

}  // namespace core
