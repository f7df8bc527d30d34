// Point and aim constraints as plain functions of positions.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace core {

// sum w_i p_i / sum w_i: the point constraint's goal. points: #T by 3;
// weights: #T, >= 0, not all 0 (normalised here).
Eigen::Vector3d weightedAverage(const Eigen::MatrixX3d& points, const std::vector<double>& weights);

// The rotation R (object frame -> model frame) that turns aim_axis to point
// from `position` at `target` and keeps R * up_axis as close to world_up as
// the aim allows (up_axis taken orthogonal to aim_axis; when world_up is
// parallel to the aim direction, the up axis is the one of smallest turn).
// aim_axis, up_axis non-zero and not parallel; target != position.
Eigen::Matrix3d aimRotation(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                            const Eigen::Vector3d& aim_axis, const Eigen::Vector3d& up_axis,
                            const Eigen::Vector3d& world_up);

}  // namespace core
