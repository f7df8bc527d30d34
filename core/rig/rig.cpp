#include "core/rig/rig.h"

#include <functional>

namespace core {

namespace {

// Rows of `values` (#V rows, or none: left alone) with the copies appended.
template <class Matrix>
void appendRowCopies(Matrix& values, Eigen::Index vertex_count, const std::vector<int>& copy_of) {
  if (values.rows() != vertex_count) return;
  Matrix grown(vertex_count + static_cast<Eigen::Index>(copy_of.size()), values.cols());
  grown.topRows(vertex_count) = values;
  for (std::size_t i = 0; i < copy_of.size(); ++i) grown.row(vertex_count + static_cast<Eigen::Index>(i)) = values.row(copy_of[i]);
  values = std::move(grown);
}

}  // namespace

Rig partAsRig(const Rig& rig, const RigPart& part) {
  Rig out;
  out.mesh = part.mesh;
  out.mesh_name = part.name;
  out.nodes = rig.nodes;
  out.mesh_node = part.node;
  if (part.weights.size() > 0) out.skin = rig.skin;
  out.weights = part.weights;
  out.morph_targets = part.morph_targets;
  out.morph_default_weights = part.morph_default_weights;
  out.attributes = part.attributes;
  out.triangle_materials = part.triangle_materials;
  return out;
}

void appendVertexCopies(Rig& rig, const std::vector<int>& copy_of) {
  if (copy_of.empty()) return;
  const Eigen::Index nv = rig.mesh.vertexCount();
  if (rig.weights.rows() == nv) {
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(static_cast<std::size_t>(rig.weights.nonZeros()) * 2);
    auto addRow = [&](Eigen::Index from, Eigen::Index to) {
      for (SkinWeights::InnerIterator it(rig.weights, from); it; ++it) {
        entries.emplace_back(static_cast<int>(to), static_cast<int>(it.col()), it.value());
      }
    };
    for (Eigen::Index v = 0; v < nv; ++v) addRow(v, v);
    for (std::size_t i = 0; i < copy_of.size(); ++i) addRow(copy_of[i], nv + static_cast<Eigen::Index>(i));
    SkinWeights grown(nv + static_cast<Eigen::Index>(copy_of.size()), rig.weights.cols());
    grown.setFromTriplets(entries.begin(), entries.end());
    rig.weights = std::move(grown);
  }
  for (MorphTarget& target : rig.morph_targets) {
    appendRowCopies(target.position_deltas, nv, copy_of);
    appendRowCopies(target.normal_deltas, nv, copy_of);
  }
  VertexAttributes& a = rig.attributes;
  for (Eigen::MatrixX2d& set : a.extra_uv_sets) appendRowCopies(set, nv, copy_of);
  appendRowCopies(a.colors, nv, copy_of);
  for (auto& [name, labels] : a.labels) appendRowCopies(labels, nv, copy_of);
  for (auto& [name, field] : a.fields) appendRowCopies(field, nv, copy_of);
  appendRowCopies(rig.mesh.normals, nv, copy_of);
  appendRowCopies(rig.mesh.uvs, nv, copy_of);
  appendRowCopies(rig.mesh.regions, nv, copy_of);
  appendRowCopies(rig.mesh.positions, nv, copy_of);  // last: its rows are the vertex count
}

std::vector<Eigen::Matrix4d> nodeWorldTransforms(const std::vector<Node>& nodes) {
  const std::size_t n = nodes.size();
  std::vector<Eigen::Matrix4d> world(n);
  std::vector<char> done(n, 0);
  // Iterative by depth: a parent is resolved before its children; cycles (an
  // invalid file) fall back to treating the node as a root.
  std::function<const Eigen::Matrix4d&(std::size_t, int)> resolve = [&](std::size_t i, int depth) -> const Eigen::Matrix4d& {
    if (done[i]) return world[i];
    Eigen::Affine3d local = Eigen::Affine3d::Identity();
    local.translate(nodes[i].translation);
    local.rotate(nodes[i].rotation.normalized());
    local.scale(nodes[i].scale);
    const int p = nodes[i].parent;
    if (p >= 0 && static_cast<std::size_t>(p) < n && depth < static_cast<int>(n)) {
      world[i] = resolve(static_cast<std::size_t>(p), depth + 1) * local.matrix();
    } else {
      world[i] = local.matrix();
    }
    done[i] = 1;
    return world[i];
  };
  for (std::size_t i = 0; i < n; ++i) resolve(i, 0);
  return world;
}

std::map<std::string, Eigen::Matrix4d> namedNodeTransforms(const Rig& rig) {
  const std::vector<Eigen::Matrix4d> world = nodeWorldTransforms(rig.nodes);
  std::map<std::string, Eigen::Matrix4d> transforms;
  for (std::size_t n = 0; n < rig.nodes.size(); ++n) {
    if (!rig.nodes[n].name.empty() && static_cast<int>(n) != rig.mesh_node) transforms.emplace(rig.nodes[n].name, world[n]);
  }
  return transforms;
}

std::map<std::string, Eigen::VectorXd> faceJointWeights(const Rig& rig) {
  std::map<std::string, Eigen::VectorXd> columns;
  if (!rig.skin || rig.weights.cols() != static_cast<Eigen::Index>(rig.skin->joints.size())) return columns;
  std::vector<Eigen::VectorXd> dense(rig.skin->joints.size(), Eigen::VectorXd::Zero(rig.weights.rows()));
  for (Eigen::Index v = 0; v < rig.weights.outerSize(); ++v) {
    for (SkinWeights::InnerIterator it(rig.weights, v); it; ++it) dense[static_cast<std::size_t>(it.col())](v) = it.value();
  }
  for (std::size_t j = 0; j < rig.skin->joints.size(); ++j) {
    const int node = rig.skin->joints[j];
    if (node >= 0 && static_cast<std::size_t>(node) < rig.nodes.size() && !rig.nodes[static_cast<std::size_t>(node)].name.empty()) {
      columns[rig.nodes[static_cast<std::size_t>(node)].name] = std::move(dense[j]);
    }
  }
  return columns;
}

}  // namespace core
