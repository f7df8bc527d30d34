#include "core/transfer/skeleton.h"

#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/LU>

namespace core {

namespace {

const Eigen::Matrix3d kIdentity3 = Eigen::Matrix3d::Identity();

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

// Skin joints and their descendants (attachments, locators): the nodes that
// move with the face.
std::vector<char> skinSubtree(const Rig& rig) {
  const std::size_t n = rig.nodes.size();
  std::vector<char> moved(n, 0);
  if (!rig.skin) return moved;
  for (int j : rig.skin->joints) if (j >= 0 && static_cast<std::size_t>(j) < n) moved[static_cast<std::size_t>(j)] = 1;
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < n; ++i) {
      const int p = rig.nodes[i].parent;
      if (!moved[i] && p >= 0 && moved[static_cast<std::size_t>(p)]) moved[i] = changed = true;
    }
  }
  return moved;
}

// `q` with its turn away from `rest` scaled by `gain`: the same axis, `gain`
// times the angle (the shorter way round from rest).
Eigen::Quaterniond exaggeratedRotation(const Eigen::Quaterniond& rest, const Eigen::Quaterniond& q, double gain) {
  Eigen::Quaterniond delta = rest.conjugate() * q.normalized();
  if (delta.w() < 0.0) delta.coeffs() = -delta.coeffs();
  const Eigen::AngleAxisd turn(delta);
  return rest * Eigen::Quaterniond(Eigen::AngleAxisd(gain * turn.angle(), turn.axis()));
}

// A cubic-spline rotation tangent `t` at key value `q` carried through the
// exaggeration: the derivative along t of the map extended to any length of
// q (|q| f(q / |q|), f the map of unit keys above), whose value at q is
// |q| `mapped`.
Eigen::Vector4d exaggeratedTangent(const Eigen::Quaterniond& rest, const Eigen::Quaterniond& q, const Eigen::Vector4d& t,
                                   double gain, const Eigen::Quaterniond& mapped) {
  const double norm = q.norm();
  if (!(norm > 0.0)) return t;
  const Eigen::Vector4d unit = q.coeffs() / norm;
  const double radial = unit.dot(t);
  const Eigen::Vector4d across = t - radial * unit;
  const double length = across.norm();
  if (length == 0.0) return radial * mapped.coeffs();
  // Central difference along the part across the unit sphere.
  const double h = 1e-6 / length;
  Eigen::Quaterniond plus, minus;
  plus.coeffs() = (unit + h * across).normalized();
  minus.coeffs() = (unit - h * across).normalized();
  Eigen::Vector4d a = exaggeratedRotation(rest, plus, gain).coeffs(), b = exaggeratedRotation(rest, minus, gain).coeffs();
  if (a.dot(mapped.coeffs()) < 0.0) a = -a;
  if (b.dot(mapped.coeffs()) < 0.0) b = -b;
  return (a - b) / (2.0 * h) + radial * mapped.coeffs();
}

}  // namespace

TransferredSkeleton transferSkeleton(const Rig& source, const TpsWarp& dense_map, const Eigen::Matrix3d& rotation) {
  TransferredSkeleton out;
  out.nodes = source.nodes;
  out.skin = source.skin;
  const std::size_t n = source.nodes.size();
  if (!source.skin || n == 0) return out;
  const std::vector<char> moved = skinSubtree(source);

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
  return out;
}

std::vector<Animation> transferAnimations(const Rig& source, const std::vector<Node>& nodes,
                                          const Eigen::Matrix3d& rotation,
                                          const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& adaptation,
                                          const AnimationTransferOptions& options) {
  std::vector<Animation> animations = source.animations;
  const std::size_t n = source.nodes.size();
  if (!source.skin || n == 0 || nodes.size() != n) return animations;
  const std::vector<char> moved = skinSubtree(source);
  const std::vector<Eigen::Matrix4d> world = nodeWorldTransforms(source.nodes);
  const std::vector<Eigen::Matrix4d> new_world = nodeWorldTransforms(nodes);

  for (auto& animation : animations) {
    for (auto& channel : animation.channels) {
      const std::size_t i = static_cast<std::size_t>(channel.node);
      if (channel.path == AnimationPath::kWeights || i >= n || !moved[i]) continue;
      const int p = source.nodes[i].parent;
      const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
      const double gain = options.exaggeration.of(source.nodes[i].name);
      if (channel.path == AnimationPath::kRotation) {
        const Eigen::Quaterniond rest = source.nodes[i].rotation.normalized();
        if (gain != 1.0) {
          // Each key on the side of the one before, so that neighbouring keys
          // interpolate the short way; a cubic key's tangents go through the
          // same map at the key's own value.
          Eigen::Quaterniond previous(1.0, 0.0, 0.0, 0.0);
          for (Eigen::Index r = cubic ? 1 : 0; r < channel.values.rows(); r += cubic ? 3 : 1) {
            const Eigen::Quaterniond q(channel.values(r, 3), channel.values(r, 0), channel.values(r, 1),
                                       channel.values(r, 2));
            Eigen::Quaterniond mapped = exaggeratedRotation(rest, q, gain);
            if (r > (cubic ? 1 : 0) && mapped.coeffs().dot(previous.coeffs()) < 0.0) mapped.coeffs() = -mapped.coeffs();
            previous = mapped;
            const double norm = q.norm();  // keep the key's length (cubic keys need not be unit)
            if (cubic) {
              for (const Eigen::Index tangent : {r - 1, r + 1}) {
                const Eigen::Vector4d t = channel.values.row(tangent).transpose();
                channel.values.row(tangent) = exaggeratedTangent(rest, q, t, gain, mapped).transpose();
              }
            }
            channel.values.row(r) << norm * mapped.x(), norm * mapped.y(), norm * mapped.z(), norm * mapped.w();
          }
        }
        // A moved subtree's root turns by the global rotation in its parent's
        // frame; deeper joints keep their local keys.
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
      if (channel.path == AnimationPath::kScale) {
        if (gain == 1.0) continue;
        // s_rest (s / s_rest)^gain per axis, where the ratio is positive; a
        // tangent is the derivative: gain (s / s_rest)^(gain - 1) ds.
        const Eigen::Vector3d rest = source.nodes[i].scale;
        const Eigen::MatrixXd keys = channel.values;
        for (Eigen::Index r = 0; r < keys.rows(); ++r) {
          const Eigen::Index value = cubic ? r - r % 3 + 1 : r;
          for (int c = 0; c < 3; ++c) {
            const double ratio = rest(c) != 0.0 ? keys(value, c) / rest(c) : 0.0;
            if (!(ratio > 0.0)) continue;
            channel.values(r, c) = cubic && r % 3 != 1 ? gain * std::pow(ratio, gain - 1.0) * keys(r, c)
                                                         : rest(c) * std::pow(ratio, gain);
          }
        }
        continue;
      }
      // Translation keys: delta from the rest translation, in the parent's
      // frame, mapped by J_local = L'_P^-1 A L_P (A: world-space adaptation at
      // the joint), times the gain.
      const Eigen::Matrix3d lp = p >= 0 ? linearPart(world[static_cast<std::size_t>(p)]) : Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d lp_new = p >= 0 ? linearPart(new_world[static_cast<std::size_t>(p)]) : Eigen::Matrix3d::Identity();
      const Eigen::Matrix3d a = adaptation(Eigen::Vector3d(world[i].topRightCorner<3, 1>()));
      const Eigen::Matrix3d local = gain * lp_new.inverse() * a * lp;
      const Eigen::Vector3d rest = source.nodes[i].translation, rest_new = nodes[i].translation;
      if (local == kIdentity3 && rest_new == rest) continue;  // keys exactly as they came
      for (Eigen::Index r = 0; r < channel.values.rows(); ++r) {
        const Eigen::Vector3d v = channel.values.row(r).transpose();
        const bool tangent = cubic && (r % 3) != 1;  // in/out tangents are derivatives: no rest offset
        const Eigen::Vector3d mapped = tangent ? Eigen::Vector3d(local * v) : Eigen::Vector3d(rest_new + local * (v - rest));
        channel.values.row(r) = mapped.transpose();
      }
    }
  }
  return animations;
}

}  // namespace core
