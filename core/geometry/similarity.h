// Least-squares similarity transform between point sets (Umeyama 1991):
// target ~= scale * rotation * source + translation; and the least-squares
// affine map.
#pragma once

#include <optional>

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

struct AffineMap {
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();  // target ~= linear * source + translation
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double rms_residual = 0.0;  // rms of the fit's misfit over the points, target units
};

// source, target: #N by 3 corresponding points. Empty when the source points
// do not span 3D (fewer than 4, or within 1e-6 of their spread of a plane),
// where the map across the plane is undetermined.
std::optional<AffineMap> fitAffine(const Eigen::MatrixX3d& source, const Eigen::MatrixX3d& target);

}  // namespace core
