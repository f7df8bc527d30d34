// carryParts: see parts.h.

#include "core/transfer/parts.h"

#include <cmath>

#include "core/geometry/mesh.h"
#include "core/geometry/similarity.h"

namespace core {

namespace {

// Rows of `m` times `a` (each row a vector): m * a^T.
Eigen::MatrixX3d turned(const Eigen::MatrixX3d& m, const Eigen::Matrix3d& a) {
  return m.rows() > 0 ? Eigen::MatrixX3d(m * a.transpose()) : m;
}

void carryRigid(const RigPart& source, const TpsWarp& dense_map, RigPart& out, CarriedPart& report) {
  const Similarity body = fitSimilarity(source.mesh.positions, dense_map.apply(source.mesh.positions));
  report.rigid = true;
  report.scale = body.scale;
  report.fit_residual = body.rms_residual;
  out.mesh.positions = (source.mesh.positions * (body.scale * body.rotation).transpose()).rowwise() +
                       body.translation.transpose();
  out.mesh.normals = turned(source.mesh.normals, body.rotation);
  // A body turned and scaled turns and scales its motion with it: an eyeball's
  // rotation about its centre stays that rotation about the moved centre.
  for (MorphTarget& target : out.morph_targets) {
    target.position_deltas = turned(target.position_deltas, body.scale * body.rotation);
    target.normal_deltas = turned(target.normal_deltas, body.rotation);
  }
}

void carryDeforming(const RigPart& source, const TpsWarp& dense_map,
                    const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& delta_adaptation,
                    const Eigen::Matrix3d& normal_rotation, RigPart& out) {
  const Eigen::MatrixX3d& p = source.mesh.positions;
  out.mesh.positions = dense_map.apply(p);
  if (source.mesh.normals.rows() > 0) {
    // Normals by the inverse transpose of the map's Jacobian (a sheet's
    // normal stays normal to it however the map stretches it).
    const std::vector<Eigen::Matrix3d> jacobians = dense_map.jacobians(p);
    for (Eigen::Index v = 0; v < p.rows(); ++v) {
      const Eigen::Matrix3d& j = jacobians[static_cast<std::size_t>(v)];
      Eigen::Vector3d n = j.inverse().transpose() * source.mesh.normals.row(v).transpose();
      if (!(n.norm() > 0.0) || !n.allFinite()) n = normal_rotation * source.mesh.normals.row(v).transpose();
      out.mesh.normals.row(v) = n.normalized().transpose();
    }
  }
  // The adaptation once per vertex that any shape moves (it may be a Jacobian of a TPS).
  std::vector<Eigen::Matrix3d> adaptation(static_cast<std::size_t>(p.rows()));
  std::vector<char> moves(static_cast<std::size_t>(p.rows()), 0);
  for (const MorphTarget& target : source.morph_targets) {
    for (Eigen::Index v = 0; v < p.rows(); ++v) moves[static_cast<std::size_t>(v)] |= !target.position_deltas.row(v).isZero(0.0);
  }
  for (Eigen::Index v = 0; v < p.rows(); ++v) {
    if (moves[static_cast<std::size_t>(v)]) adaptation[static_cast<std::size_t>(v)] = delta_adaptation(p.row(v).transpose());
  }
  for (MorphTarget& target : out.morph_targets) {
    for (Eigen::Index v = 0; v < p.rows(); ++v) {
      if (!moves[static_cast<std::size_t>(v)]) continue;
      target.position_deltas.row(v) = (adaptation[static_cast<std::size_t>(v)] * target.position_deltas.row(v).transpose()).transpose();
    }
    target.normal_deltas = turned(target.normal_deltas, normal_rotation);
  }
}

}  // namespace

void dropPartChannels(std::vector<RigPart>& parts, bool shapes, bool skinned) {
  for (RigPart& part : parts) {
    if (!shapes) {
      part.morph_targets.clear();
      part.morph_default_weights.resize(0);
    }
    if (!skinned) part.weights = SkinWeights();
  }
}

CarriedParts carryParts(const std::vector<RigPart>& parts, const TpsWarp& dense_map,
                        const std::function<Eigen::Matrix3d(const Eigen::Vector3d&)>& delta_adaptation,
                        const Eigen::Matrix3d& normal_rotation) {
  CarriedParts out;
  for (const RigPart& source : parts) {
    RigPart part = source;  // topology, order, UVs, attributes, weights kept
    CarriedPart report;
    report.name = source.name;
    if (isSolid(source.mesh) && source.mesh.vertexCount() >= 4) {
      carryRigid(source, dense_map, part, report);
    } else {
      carryDeforming(source, dense_map, delta_adaptation, normal_rotation, part);
    }
    out.parts.push_back(std::move(part));
    out.report.push_back(std::move(report));
  }
  return out;
}

}  // namespace core
