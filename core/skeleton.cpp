#include <Eigen/LU>

#include "core/skeleton.h"

namespace core {

namespace {

Eigen::Matrix3d linearPart(const Eigen::Matrix4d& m) { return m.topLeftCorner<3, 3>(); }

// Local TRS from a local matrix whose linear part is rotation * diag(scale).
void setLocal(Node& node, const Eigen::Matrix4d& local) {
  node.translation = local.topRightCorner<3, 1>();
  const Eigen::Matrix3d l = local.topLeftCorner<3, 3>();
  Eigen::Vector3d scale(l.col(0).norm(), l.col(1).norm(), l.col(2).norm());
  Eigen::Matrix3d r = l;
  for (int c = 0; c < 3; ++c) if (scale(c) > 0) r.col(c) /= scale(c);
  if (r.determinant() < 0) {  // mirrored: carry the sign in the scale
    scale(0) = -scale(0);
    r.col(0) = -r.col(0);
  }
  node.rotation = Eigen::Quaterniond(r).normalized();
  node.scale = scale;
}

}  // namespace

TransferredSkeleton transferSkeleton(const Rig& source, const TpsWarp& dense_map, const Eigen::Matrix3d& rotation,
                                     const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& adaptation,
                                     const SkeletonTransferOptions& options) {
  TransferredSkeleton out;
  out.nodes = source.nodes;
  out.skin = source.skin;
  out.animations = source.animations;
  const std::size_t n = source.nodes.size();
  if (!source.skin || n == 0) return out;

  // Nodes that move: skin joints and their descendants (attachments, locators).
  std::vector<char> moved(n, 0);
  for (int j : source.skin->joints) if (j >= 0 && static_cast<std::size_t>(j) < n) moved[static_cast<std::size_t>(j)] = 1;
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < n; ++i) {
      const int p = source.nodes[i].parent;
      if (!moved[i] && p >= 0 && moved[static_cast<std::size_t>(p)]) moved[i] = changed = true;
    }
  }

  // New world transforms: position through the dense map, orientation turned
  // by the global rotation, scale kept.
  const std::vector<Eigen::Matrix4d> world = nodeWorldTransforms(source.nodes);
  std::vector<Eigen::Matrix4d> new_world = world;
  for (std::size_t i = 0; i < n; ++i) {
    if (!moved[i]) continue;
    new_world[i].topLeftCorner<3, 3>() = rotation * linearPart(world[i]);
    new_world[i].topRightCorner<3, 1>() = dense_map.apply(Eigen::Vector3d(world[i].topRightCorner<3, 1>()));
    ++out.moved_nodes;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!moved[i]) continue;
    const int p = source.nodes[i].parent;
    const Eigen::Matrix4d parent = p >= 0 ? new_world[static_cast<std::size_t>(p)] : Eigen::Matrix4d::Identity();
    setLocal(out.nodes[i], parent.inverse() * new_world[i]);
  }

  // Inverse binds: the bind pose moves like the rest pose (bind position
  // through the dense map, orientation turned), so rest mesh == bind pose.
  for (std::size_t k = 0; k < source.skin->joints.size(); ++k) {
    const Eigen::Matrix4d bind = source.skin->inverse_bind[k].inverse();
    Eigen::Matrix4d new_bind = bind;
    new_bind.topLeftCorner<3, 3>() = rotation * linearPart(bind);
    new_bind.topRightCorner<3, 1>() = dense_map.apply(Eigen::Vector3d(bind.topRightCorner<3, 1>()));
    Eigen::Matrix4d ib = new_bind.inverse();
    ib.row(3) << 0, 0, 0, 1;
    out.skin->inverse_bind[k] = ib;
  }

  // Translation keys: delta from the rest translation, in the parent's frame,
  // mapped by J_local = L'_P^-1 A L_P (A: world-space adaptation at the joint).
  for (auto& animation : out.animations) {
    for (auto& channel : animation.channels) {
      if (channel.path == AnimationPath::kRotation) {
        // A moved subtree's root turns by the global rotation in its parent's
        // frame; deeper joints keep their local keys.
        const std::size_t i = static_cast<std::size_t>(channel.node);
        if (i >= n || !moved[i]) continue;
        const int p = source.nodes[i].parent;
        if (p >= 0 && moved[static_cast<std::size_t>(p)]) continue;
        Eigen::Matrix3d lp = p >= 0 ? linearPart(world[static_cast<std::size_t>(p)]) : Eigen::Matrix3d::Identity();
        for (int c = 0; c < 3; ++c) lp.col(c).normalize();
        const Eigen::Quaterniond turn(Eigen::Matrix3d(lp.transpose() * rotation * lp));
        // Cubic-spline tangents are linear in the quaternion: they turn alike.
        for (Eigen::Index r = 0; r < channel.values.rows(); ++r) {
          const Eigen::Quaterniond q(channel.values(r, 3), channel.values(r, 0), channel.values(r, 1), channel.values(r, 2));
          const Eigen::Quaterniond t = turn * q;
          channel.values.row(r) << t.x(), t.y(), t.z(), t.w();
        }
        continue;
      }
      if (channel.path != AnimationPath::kTranslation) continue;
      const std::size_t i = static_cast<std::size_t>(channel.node);
      if (i >= n || !moved[i]) continue;
      const int p = source.nodes[i].parent;
      const Eigen::Matrix3d lp = p >= 0 ? linearPart(world[static_cast<std::size_t>(p)]) : Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d lp_new = p >= 0 ? linearPart(new_world[static_cast<std::size_t>(p)]) : Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d a = adaptation(Eigen::Vector3d(world[i].topRightCorner<3, 1>()));
      const auto found = options.per_joint.find(source.nodes[i].name);
      const double gain = found != options.per_joint.end() ? found->second : options.exaggeration;
      const Eigen::Matrix3d local = gain * lp_new.inverse() * a * lp;
      const Eigen::Vector3d rest = source.nodes[i].translation, rest_new = out.nodes[i].translation;
      const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
      for (Eigen::Index r = 0; r < channel.values.rows(); ++r) {
        const Eigen::Vector3d v = channel.values.row(r).transpose();
        const bool tangent = cubic && (r % 3) != 1;  // in/out tangents are derivatives: no rest offset
        const Eigen::Vector3d mapped = tangent ? Eigen::Vector3d(local * v) : Eigen::Vector3d(rest_new + local * (v - rest));
        channel.values.row(r) = mapped.transpose();
      }
    }
  }
  return out;
}

}  // namespace core
