// Umeyama, "Least-squares estimation of transformation parameters between two
// point patterns", PAMI 1991.
#include "core/similarity.h"

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

}  // namespace core
