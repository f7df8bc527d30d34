// Cluster transforms and muscle transforms.
#include "core/components/cluster.h"

#include <cassert>
#include <numbers>

namespace core {

Eigen::Affine3d clusterTransform(const Eigen::Vector3d& pivot, const Eigen::Vector3d& translate,
                                 const Eigen::Matrix3d& rotation, const Eigen::Vector3d& scale) {
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  t.linear() = rotation * scale.asDiagonal();
  t.translation() = pivot + translate - t.linear() * pivot;
  return t;
}

void applyCluster(Eigen::MatrixX3d& positions, const std::vector<ClusterMember>& members,
                  const Eigen::Affine3d& transform) {
  for (const ClusterMember& m : members) {
    assert(m.vertex >= 0 && m.vertex < positions.rows());
    const Eigen::Vector3d p = positions.row(m.vertex).transpose();
    positions.row(m.vertex) += (m.weight * (transform * p - p)).transpose();
  }
}

Eigen::Matrix3d eulerDegreesToRotation(const Eigen::Vector3d& degrees) {
  const Eigen::Vector3d r = degrees * (std::numbers::pi / 180.0);
  return (Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Affine3d muscleTransform(const Eigen::Vector3d& origin, const Eigen::Vector3d& insertion, double contraction,
                                MuscleDriveMode mode, double weight) {
  const Eigen::Vector3d axis = insertion - origin;
  assert(axis.norm() > 0.0);
  const double amount = weight * contraction;
  Eigen::Affine3d t = Eigen::Affine3d::Identity();
  if (mode == MuscleDriveMode::kTranslate) {
    t.translation() = -amount * axis;
    return t;
  }
  const Eigen::Vector3d a = axis.normalized();
  t.linear() = Eigen::Matrix3d::Identity() - amount * a * a.transpose();
  t.translation() = origin - t.linear() * origin;
  return t;
}

}  // namespace core
