// Umeyama, "Least-squares estimation of transformation parameters between two
// point patterns", PAMI 1991.
#include "core/geometry/similarity.h"

#include <cmath>

#include <Eigen/LU>
#include <Eigen/SVD>

namespace core {

Similarity fitSimilarity(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target) {
  Similarity s;
  const Eigen::Index n = source.rows();
  if (n == 0) return s;
  const Eigen::RowVector3d ms = source.colwise().mean(), mt = target.colwise().mean();
  const Eigen::MatrixX3d a = source.rowwise() - ms, b = target.rowwise() - mt;
  const Eigen::Matrix3d cov = b.transpose() * a / static_cast<double>(n);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) d(2, 2) = -1;
  s.rotation = svd.matrixU() * d * svd.matrixV().transpose();
  const double var = a.rowwise().squaredNorm().mean();
  s.scale = var > 0 ? (svd.singularValues().asDiagonal() * d).trace() / var : 1.0;
  s.translation = mt.transpose() - s.scale * s.rotation * ms.transpose();
  const Eigen::MatrixX3d aligned =
      ((s.scale * source * s.rotation.transpose()).rowwise() + s.translation.transpose()).eval();
  s.rms_residual = std::sqrt((aligned - target).rowwise().squaredNorm().mean());
  return s;
}

std::optional<AffineMap> fitAffine(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target) {
  const Eigen::Index n = source.rows();
  if (n < 4 || target.rows() != n) return std::nullopt;
  // Centred, the normal equations are 3x3: linear = (B^T A)(A^T A)^-1.
  const Eigen::RowVector3d ms = source.colwise().mean(), mt = target.colwise().mean();
  const Eigen::MatrixX3d a = source.rowwise() - ms, b = target.rowwise() - mt;
  const Eigen::Matrix3d ata = a.transpose() * a;
  Eigen::JacobiSVD<Eigen::Matrix3d> spread(ata);
  const Eigen::Vector3d sv = spread.singularValues();  // squared spreads along the principal axes
  if (!(sv(2) > 1e-12 * sv(0))) return std::nullopt;
  AffineMap m;
  m.linear = (b.transpose() * a) * ata.inverse();
  m.translation = mt.transpose() - m.linear * ms.transpose();
  const Eigen::MatrixX3d mapped = ((source * m.linear.transpose()).rowwise() + m.translation.transpose()).eval();
  m.rms_residual = std::sqrt((mapped - target).rowwise().squaredNorm().mean());
  return m;
}

}  // namespace core
