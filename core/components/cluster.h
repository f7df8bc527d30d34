// Clusters (a weighted transform about a pivot) and the muscle transform that
// drives them (a joint scaled about its origin toward its insertion, as in
// muscle-based face rigs).
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/components/components.h"

namespace core {

// p -> pivot + translate + rotation * diag(scale) * (p - pivot): the cluster's
// transform of model space (model units).
Eigen::Affine3d clusterTransform(const Eigen::Vector3d& pivot, const Eigen::Vector3d& translate,
                                 const Eigen::Matrix3d& rotation, const Eigen::Vector3d& scale);

// positions: #V by 3. Each member vertex v moves to p + weight * (transform(p) - p),
// in place.
void applyCluster(Eigen::MatrixX3d& positions, const std::vector<ClusterMember>& members,
                  const Eigen::Affine3d& transform);

// Rotation of Euler angles in degrees applied X, then Y, then Z (fixed axes):
// Rz * Ry * Rx.
Eigen::Matrix3d eulerDegreesToRotation(const Eigen::Vector3d& degrees);

// The transform a muscle of contraction c applies to what it drives, with a
// = (insertion - origin) / |insertion - origin|:
//   kAxialScale: p -> p - weight*c * ((p - origin) . a) a   (scaled about the origin along a by 1 - weight*c)
//   kTranslate:  p -> p - weight*c * (insertion - origin)
// origin != insertion.
Eigen::Affine3d muscleTransform(const Eigen::Vector3d& origin, const Eigen::Vector3d& insertion, double contraction,
                                MuscleDriveMode mode, double weight);

}  // namespace core
