// Posing a rig: sample its animation at a time and deform the mesh by morph
// targets then linear blend skinning (glTF 2.0 semantics). Used to measure
// animation fidelity (papers 000 sec. 5.3.1 strain) and by tests.
#pragma once

#include <vector>

#include "core/rig/rig.h"

namespace core {

struct Pose {
  std::vector<Node> nodes;        // local TRS at the sampled time
  Eigen::VectorXd morph_weights;  // #targets
};

// Rest pose with every channel of `animation` sampled at `time` (seconds;
// clamped to the key range). LINEAR uses slerp for rotations, CUBICSPLINE the
// glTF Hermite form.
Pose samplePose(const Rig& rig, const Animation& animation, double time);

// #V by 3 posed positions: rest + sum_k w_k delta_k, then skinned (when the
// rig has a skin) with M_j = world_j(pose) * inverse_bind_j.
Eigen::MatrixX3d poseMesh(const Rig& rig, const Pose& pose);

// #V by 3 bind-space positions that, skinned at `rest_nodes`, land where
// `positions` skinned at `posed_nodes` land: a pose of the skeleton held by
// the mesh alone, as a morph target holds it. Per vertex p -> B^-1 B' p with
// B, B' its blended skinning matrices at rest and posed; a vertex none of
// whose joints moves is kept as it is. `weights`: #V by skin.joints.size().
Eigen::MatrixX3d holdSkeletonPose(const Skin& skin, const SkinWeights& weights, const std::vector<Node>& rest_nodes,
                                  const std::vector<Node>& posed_nodes, Eigen::MatrixX3d positions);

}  // namespace core
