// Skeleton and animation transfer (papers 000 ch. 4.7.2 "Facial Animation
// Transfer", fig. 5.3): joints move through the dense map, keep their
// orientation (turned by the global rotation between the faces), inverse bind
// matrices are recomputed so the target rest mesh is the bind pose; joint
// translation keys are mapped by the local adaptation in the parent's frame,
// rotations and morph-weight keys are kept. Movement exaggeration (papers 000
// sec. 5.4.2) scales each animated joint's motion away from its rest pose.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/rig/rig.h"
#include "core/solve/tps.h"

namespace core {

struct TransferredSkeleton {
  std::vector<Node> nodes;
  std::optional<Skin> skin;
  int moved_nodes = 0;
};

// `rotation`: global rotation source -> target (orientation of moved joints).
// Moved: skin joints and their descendants (attachments, locators).
TransferredSkeleton transferSkeleton(const Rig& source, const TpsWarp& dense_map, const Eigen::Matrix3d& rotation);

struct AnimationTransferOptions {
  // Gain on animated motion away from rest, by joint name (translations, rotation angles, log scale).
  Exaggeration exaggeration;
};
// The source's animations on `nodes` (the transferred skeleton, or the
// source's own when joints are not transferred). `rotation` and
// `adaptation(p)` (3x3 map of a world-space delta at source point p) as for
// the joints: a moved subtree's root turns its rotation keys, translation
// keys are mapped by J_local = L'_P^-1 A L_P in the parent's frame.
std::vector<Animation> transferAnimations(const Rig& source, const std::vector<Node>& nodes,
                                          const Eigen::Matrix3d& rotation,
                                          const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& adaptation,
                                          const AnimationTransferOptions& options = {});

}  // namespace core
