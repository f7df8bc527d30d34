// Least-squares similarity transform between point sets (Umeyama 1991):
// target ~= scale * rotation * source + translation.
#pragma once

#include <Eigen/Core>

namespace core {

struct Similarity {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // proper rotation (det +1)
  double scale = 1.0;
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double rms_residual = 0.0;  // rms of |apply(source_i) - target_i| over the fitted points, target units
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return scale * rotation * p + translation; }
};

// source, target: #N by 3 corresponding points (N >= 3, not collinear).
Similarity fitSimilarity(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target);

}  // namespace core
