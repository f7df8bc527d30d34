#include <Eigen/LU>

#include "core/rig/skinning.h"

#include <algorithm>

namespace core {

namespace {

// Index k and fraction u with times(k) <= t < times(k+1).
void bracket(const Eigen::VectorXd& times, double t, Eigen::Index& k, double& u) {
  const Eigen::Index n = times.size();
  if (n <= 1 || t <= times(0)) {
    k = 0;
    u = 0.0;
    return;
  }
  if (t >= times(n - 1)) {
    k = n - 1;
    u = 0.0;
    return;
  }
  k = std::upper_bound(times.data(), times.data() + n, t) - times.data() - 1;
  const double dt = times(k + 1) - times(k);
  u = dt > 0 ? (t - times(k)) / dt : 0.0;
}

Eigen::VectorXd sampleChannel(const AnimationChannel& c, double t) {
  Eigen::Index k;
  double u;
  bracket(c.times, t, k, u);
  const Eigen::Index n = c.times.size();
  const bool cubic = c.interpolation == Interpolation::kCubicSpline;
  auto value = [&](Eigen::Index i) -> Eigen::VectorXd { return c.values.row(cubic ? 3 * i + 1 : i).transpose(); };
  if (c.interpolation == Interpolation::kStep || u == 0.0 || k + 1 >= n) return value(k);
  if (cubic) {
    const double dt = c.times(k + 1) - c.times(k);
    const Eigen::VectorXd p0 = value(k), p1 = value(k + 1);
    const Eigen::VectorXd m0 = dt * c.values.row(3 * k + 2).transpose(), m1 = dt * c.values.row(3 * (k + 1)).transpose();
    const double u2 = u * u, u3 = u2 * u;
    Eigen::VectorXd r = (2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1 + (u3 - u2) * m1;
    if (c.path == AnimationPath::kRotation) r.normalize();
    return r;
  }
  if (c.path == AnimationPath::kRotation) {
    const Eigen::VectorXd a = value(k), b = value(k + 1);
    const Eigen::Quaterniond qa(a(3), a(0), a(1), a(2)), qb(b(3), b(0), b(1), b(2));
    const Eigen::Quaterniond q = qa.slerp(u, qb);
    Eigen::VectorXd r(4);
    r << q.x(), q.y(), q.z(), q.w();
    return r;
  }
  return (1 - u) * value(k) + u * value(k + 1);
}

}  // namespace

Pose samplePose(const Rig& rig, const Animation& animation, double time) {
  Pose pose;
  pose.nodes = rig.nodes;
  pose.morph_weights = rig.morph_default_weights.size() == static_cast<Eigen::Index>(rig.morph_targets.size())
                           ? rig.morph_default_weights
                           : Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rig.morph_targets.size()));
  for (const auto& c : animation.channels) {
    if (c.node < 0 || static_cast<std::size_t>(c.node) >= pose.nodes.size() || c.times.size() == 0) continue;
    const Eigen::VectorXd v = sampleChannel(c, time);
    Node& node = pose.nodes[static_cast<std::size_t>(c.node)];
    switch (c.path) {
      case AnimationPath::kTranslation: node.translation = v.head<3>(); break;
      case AnimationPath::kScale: node.scale = v.head<3>(); break;
      case AnimationPath::kRotation: node.rotation = Eigen::Quaterniond(v(3), v(0), v(1), v(2)).normalized(); break;
      case AnimationPath::kWeights:
        if (v.size() == pose.morph_weights.size()) pose.morph_weights = v;
        break;
    }
  }
  return pose;
}

Eigen::MatrixX3d poseMesh(const Rig& rig, const Pose& pose) {
  Eigen::MatrixX3d morphed = rig.mesh.positions;
  for (std::size_t k = 0; k < rig.morph_targets.size(); ++k) {
    const double w = pose.morph_weights(static_cast<Eigen::Index>(k));
    if (w != 0.0) morphed += w * rig.morph_targets[k].position_deltas;
  }
  if (!rig.skin) return morphed;
  const std::vector<Eigen::Matrix4d> world = nodeWorldTransforms(pose.nodes);
  std::vector<Eigen::Matrix4d> skinning(rig.skin->joints.size());
  for (std::size_t j = 0; j < skinning.size(); ++j) {
    skinning[j] = world[static_cast<std::size_t>(rig.skin->joints[j])] * rig.skin->inverse_bind[j];
  }
  Eigen::MatrixX3d out = Eigen::MatrixX3d::Zero(morphed.rows(), 3);
  for (Eigen::Index v = 0; v < morphed.rows(); ++v) {
    const Eigen::Vector4d x(morphed(v, 0), morphed(v, 1), morphed(v, 2), 1.0);
    Eigen::Vector4d y = Eigen::Vector4d::Zero();
    for (SkinWeights::InnerIterator it(rig.weights, v); it; ++it) y += it.value() * (skinning[static_cast<std::size_t>(it.col())] * x);
    out.row(v) = y.head<3>().transpose();
  }
  return out;
}

Eigen::MatrixX3d holdSkeletonPose(const Skin& skin, const SkinWeights& weights, const std::vector<Node>& rest_nodes,
                                  const std::vector<Node>& posed_nodes, Eigen::MatrixX3d positions) {
  const std::vector<Eigen::Matrix4d> rest_world = nodeWorldTransforms(rest_nodes);
  const std::vector<Eigen::Matrix4d> posed_world = nodeWorldTransforms(posed_nodes);
  const std::size_t count = skin.joints.size();
  std::vector<Eigen::Matrix4d> rest(count), posed(count);
  std::vector<char> moved(count, 0);
  bool any = false;
  for (std::size_t j = 0; j < count; ++j) {
    const auto node = static_cast<std::size_t>(skin.joints[j]);
    rest[j] = rest_world[node] * skin.inverse_bind[j];
    posed[j] = posed_world[node] * skin.inverse_bind[j];
    moved[j] = posed_world[node] != rest_world[node] ? 1 : 0;
    any = any || moved[j];
  }
  if (!any) return positions;
  for (Eigen::Index v = 0; v < positions.rows() && v < weights.rows(); ++v) {
    Eigen::Matrix4d at_rest = Eigen::Matrix4d::Zero(), at_pose = Eigen::Matrix4d::Zero();
    bool moves = false;
    for (SkinWeights::InnerIterator it(weights, v); it; ++it) {
      const auto j = static_cast<std::size_t>(it.col());
      at_rest += it.value() * rest[j];
      at_pose += it.value() * posed[j];
      moves = moves || (moved[j] && it.value() != 0.0);
    }
    if (!moves) continue;
    const Eigen::Vector4d x(positions(v, 0), positions(v, 1), positions(v, 2), 1.0);
    const Eigen::Vector4d held = at_rest.fullPivLu().solve(at_pose * x);
    if (held.allFinite()) positions.row(v) = held.head<3>().transpose();
  }
  return positions;
}

}  // namespace core
