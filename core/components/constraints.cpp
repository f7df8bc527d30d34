// Point constraint (normalised weighted average) and aim constraint (an
// orthonormal frame from the aim direction and the up vector).
#include "core/components/constraints.h"

#include <cassert>
#include <cmath>

#include <Eigen/Geometry>

namespace core {

Eigen::Vector3d weightedAverage(const Eigen::MatrixX3d& points, const std::vector<double>& weights) {
  assert(points.rows() == static_cast<Eigen::Index>(weights.size()));
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double total = 0.0;
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    sum += weights[static_cast<std::size_t>(i)] * points.row(i).transpose();
    total += weights[static_cast<std::size_t>(i)];
  }
  assert(total > 0.0);
  return sum / total;
}

namespace {

// Columns: aim, up (orthogonal to aim), aim x up. A right-handed frame.
Eigen::Matrix3d frame(const Eigen::Vector3d& aim, const Eigen::Vector3d& up) {
  const Eigen::Vector3d a = aim.normalized();
  const Eigen::Vector3d u = (up - up.dot(a) * a).normalized();
  Eigen::Matrix3d f;
  f.col(0) = a;
  f.col(1) = u;
  f.col(2) = a.cross(u);
  return f;
}

}  // namespace

Eigen::Matrix3d aimRotation(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                            const Eigen::Vector3d& aim_axis, const Eigen::Vector3d& up_axis,
                            const Eigen::Vector3d& world_up) {
  const Eigen::Vector3d direction = (target - position).normalized();
  const Eigen::Matrix3d local = frame(aim_axis, up_axis);
  Eigen::Vector3d up = world_up;
  if ((world_up - world_up.dot(direction) * direction).norm() < 1e-9 * world_up.norm()) {
    // world_up along the aim: keep the up axis the smallest turn of the aim takes it to.
    up = Eigen::Quaterniond::FromTwoVectors(aim_axis, direction) * local.col(1);
  }
  return frame(direction, up) * local.transpose();
}

}  // namespace core
