// Skeleton and animation transfer (papers 000 ch. 4.7.2 "Facial Animation
// Transfer", fig. 5.3): joints move through the dense map, keep their
// orientation (turned by the global rotation between the faces), inverse bind
// matrices are recomputed so the target rest mesh is the bind pose; joint
// translation keys are mapped by the local adaptation in the parent's frame,
// rotations and morph-weight keys are kept.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/rig.h"
#include "core/tps.h"

namespace core {

struct SkeletonTransferOptions {
  double exaggeration = 1.0;                // scales animated translation deltas
  std::map<std::string, double> per_joint;  // overrides `exaggeration` by joint (node) name
};

struct TransferredSkeleton {
  std::vector<Node> nodes;
  std::optional<Skin> skin;
  std::vector<Animation> animations;
  int moved_nodes = 0;
};

// `rotation`: global rotation source -> target (orientation of moved joints).
// `adaptation(p)`: 3x3 map of a world-space delta at source point p.
TransferredSkeleton transferSkeleton(const Rig& source, const TpsWarp& dense_map, const Eigen::Matrix3d& rotation,
                                     const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& adaptation,
                                     const SkeletonTransferOptions& options = {});

}  // namespace core
