// glTF rig reading, the skeleton: nodes (TRS), the skin, inverse binds and
// the influence sets of the chosen mesh merged into per-vertex weights.

#include "core/io/gltf_model.h"

namespace core::gltf {

namespace {

// ---------------------------------------------------------------------------
// Rig reading: nodes, skin and weights, morph targets, animations and vertex
// attributes of the mesh chosen above (after buildMesh has read and checked
// its primitives).

// Weight rows further than this from a sum of 1 are reported as renormalised
// (every non-empty row is divided by its sum anyway).
constexpr double kWeightSumTolerance = 1e-5;

// Closest translation * rotation * scale to a node matrix (spec,
// "Transformations"). `exact` is false when the matrix has shear or a
// projective row, which TRS cannot hold.
struct Trs {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  bool exact = true;
};

Trs decomposeTrs(const Eigen::Matrix4d& m) {
  Trs trs;
  trs.translation = m.topRightCorner<3, 1>();
  const Eigen::Matrix3d linear = m.topLeftCorner<3, 3>();
  for (int i = 0; i < 3; ++i) trs.scale(i) = linear.col(i).norm();
  if (linear.determinant() < 0.0) trs.scale(0) = -trs.scale(0);  // a mirror is one negative scale
  Eigen::Matrix3d unscaled = Eigen::Matrix3d::Zero();
  for (int i = 0; i < 3; ++i) {
    if (trs.scale(i) != 0.0) unscaled.col(i) = linear.col(i) / trs.scale(i);
  }
  // Closest rotation to the unscaled columns (polar decomposition by SVD).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(unscaled, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d u = svd.matrixU();
  Eigen::Matrix3d rotation = u * svd.matrixV().transpose();
  if (rotation.determinant() < 0.0) {
    u.col(2) = -u.col(2);
    rotation = u * svd.matrixV().transpose();
  }
  trs.rotation = Eigen::Quaterniond(rotation).normalized();
  const double tolerance = 1e-6 * std::max(1.0, linear.cwiseAbs().maxCoeff());
  trs.exact = (rotation * trs.scale.asDiagonal() - linear).cwiseAbs().maxCoeff() <= tolerance &&
              (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() <= 1e-12;
  return trs;
}

}  // namespace

Result<std::vector<Node>> readNodes(const tinygltf::Model& model, const std::string& label,
                                    std::vector<std::string>& warnings) {
  auto parents = nodeParents(model, label);
  if (!parents) return parents.error();
  const std::size_t n = model.nodes.size();
  std::vector<Node> nodes(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::size_t steps = 0;
    for (int p = (*parents)[i]; p != -1; p = (*parents)[static_cast<std::size_t>(p)]) {
      if (++steps > n) return parseError(label, "the node hierarchy has a cycle through node " + std::to_string(i));
    }
    const tinygltf::Node& gnode = model.nodes[i];
    auto local = localTransform(gnode, static_cast<int>(i), label);  // checks sizes and finiteness
    if (!local) return local.error();
    Node& node = nodes[i];
    node.name = gnode.name;
    node.parent = (*parents)[i];
    if (!gnode.matrix.empty()) {
      const Trs trs = decomposeTrs(*local);
      node.translation = trs.translation;
      node.rotation = trs.rotation;
      node.scale = trs.scale;
      if (!trs.exact) {
        warnings.push_back("node " + std::to_string(i) + quoted(gnode.name) +
                           " matrix has shear or a projective row; the closest translation/rotation/scale was kept");
      }
      continue;
    }
    const auto& t = gnode.translation;
    const auto& r = gnode.rotation;
    const auto& s = gnode.scale;
    if (!t.empty()) node.translation = Eigen::Vector3d(t[0], t[1], t[2]);
    if (!r.empty()) node.rotation = Eigen::Quaterniond(r[3], r[0], r[1], r[2]).normalized();
    if (!s.empty()) node.scale = Eigen::Vector3d(s[0], s[1], s[2]);
  }
  return nodes;
}

namespace {

std::string jointName(const tinygltf::Model& model, const std::vector<int>& joints, std::size_t j) {
  const int node = joints[j];
  return "joint " + std::to_string(j) + " (node " + std::to_string(node) +
         quoted(model.nodes[static_cast<std::size_t>(node)].name) + ")";
}

Status readInverseBinds(const tinygltf::Model& model, const tinygltf::Skin& gskin, const std::string& what,
                        const std::string& label, std::vector<std::string>& warnings, Skin& skin) {
  const std::size_t count = skin.joints.size();
  skin.inverse_bind.assign(count, Eigen::Matrix4d::Identity());  // spec: identity when absent
  if (gskin.inverseBindMatrices < 0) return Ok{};
  auto ibm = readAccessor(model, gskin.inverseBindMatrices, what + " inverseBindMatrices", label);
  if (!ibm) return ibm.error();
  if (ibm->components != 16) return parseError(label, what + " inverseBindMatrices accessor is not MAT4");
  if (ibm->count < count) {
    return parseError(label, what + " has " + std::to_string(count) + " joints but " + std::to_string(ibm->count) +
                                 " inverse bind matrices");
  }
  if (ibm->count > count) {
    warnings.push_back(what + " has " + std::to_string(ibm->count - count) +
                       " inverse bind matrices beyond its joints");
  }
  for (std::size_t j = 0; j < count; ++j) {
    Eigen::Matrix4d& m = skin.inverse_bind[j];
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 4; ++r) m(r, c) = ibm->at(j, c * 4 + r);  // column-major in the file
    }
    const std::string joint = what + " " + jointName(model, skin.joints, j);
    if (!m.allFinite()) {
      return makeError(ErrorCode::kInvalidMesh, label + ": " + joint + " inverse bind matrix is not finite");
    }
    if ((m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-6) {
      return makeError(ErrorCode::kInvalidMesh,
                       label + ": " + joint + " inverse bind matrix bottom row is not 0 0 0 1 (not affine)");
    }
    m.row(3) = Eigen::RowVector4d(0, 0, 0, 1);
  }
  return Ok{};
}

Result<Skin> readSkin(const tinygltf::Model& model, int index, const std::string& label,
                      std::vector<std::string>& warnings) {
  if (index < 0 || static_cast<std::size_t>(index) >= model.skins.size()) {
    return parseError(label, "the mesh node uses skin " + std::to_string(index) + " but the file has " +
                                 std::to_string(model.skins.size()));
  }
  const tinygltf::Skin& gskin = model.skins[static_cast<std::size_t>(index)];
  const std::string what = "skin " + std::to_string(index) + quoted(gskin.name);
  if (gskin.joints.empty()) return parseError(label, what + " has no joints");
  const std::size_t node_count = model.nodes.size();
  std::vector<char> used(node_count, 0);
  for (std::size_t j = 0; j < gskin.joints.size(); ++j) {
    const int node = gskin.joints[j];
    if (node < 0 || static_cast<std::size_t>(node) >= node_count) {
      return parseError(label, what + " joint " + std::to_string(j) + " refers to node " + std::to_string(node) +
                                   " but the file has " + std::to_string(node_count) + " nodes");
    }
    if (used[static_cast<std::size_t>(node)]) {
      return parseError(label, what + " joint " + std::to_string(j) + " repeats node " + std::to_string(node));
    }
    used[static_cast<std::size_t>(node)] = 1;
  }
  if (gskin.skeleton >= 0 && static_cast<std::size_t>(gskin.skeleton) >= node_count) {
    return parseError(label, what + " skeleton refers to node " + std::to_string(gskin.skeleton) +
                                 " but the file has " + std::to_string(node_count) + " nodes");
  }
  Skin skin;
  skin.name = gskin.name;
  skin.joints = gskin.joints;
  skin.skeleton = gskin.skeleton >= 0 ? gskin.skeleton : -1;
  if (auto ok = readInverseBinds(model, gskin, what, label, warnings, skin); !ok) return ok.error();
  return skin;
}

}  // namespace

int sameVerticesAs(const tinygltf::Mesh& gmesh, std::size_t p) {
  const tinygltf::Primitive& primitive = gmesh.primitives[p];
  for (std::size_t q = 0; q < p; ++q) {
    const tinygltf::Primitive& earlier = gmesh.primitives[q];
    if (earlier.attributes == primitive.attributes && earlier.targets == primitive.targets) {
      return static_cast<int>(q);  // the first such primitive, itself not a repeat
    }
  }
  return -1;
}

std::vector<PrimitiveRange> primitiveRanges(const tinygltf::Model& model, const tinygltf::Mesh& gmesh) {
  std::vector<PrimitiveRange> ranges;
  Eigen::Index offset = 0;
  for (std::size_t p = 0; p < gmesh.primitives.size(); ++p) {
    if (const int same = sameVerticesAs(gmesh, p); same >= 0) {
      ranges.push_back(ranges[static_cast<std::size_t>(same)]);
      continue;
    }
    const int position = gmesh.primitives[p].attributes.at("POSITION");  // buildMesh has read it
    const auto count = static_cast<Eigen::Index>(model.accessors[static_cast<std::size_t>(position)].count);
    ranges.push_back({offset, count});
    offset += count;
  }
  return ranges;
}

Eigen::Index vertexTotal(const std::vector<PrimitiveRange>& ranges) {
  Eigen::Index total = 0;
  for (const PrimitiveRange& range : ranges) total = std::max(total, range.offset + range.count);
  return total;
}

std::vector<int> attributeAccessors(const tinygltf::Mesh& gmesh, const std::string& name, int target) {
  std::vector<int> accessors;
  for (const tinygltf::Primitive& primitive : gmesh.primitives) {
    const std::map<std::string, int>& attributes =
        target < 0 ? primitive.attributes : primitive.targets[static_cast<std::size_t>(target)];
    const auto it = attributes.find(name);
    accessors.push_back(it == attributes.end() ? -1 : it->second);
  }
  return accessors;
}

bool presentInAll(const std::vector<int>& accessors) {
  return std::all_of(accessors.begin(), accessors.end(), [](int a) { return a >= 0; });
}

bool presentInAny(const std::vector<int>& accessors) {
  return std::any_of(accessors.begin(), accessors.end(), [](int a) { return a >= 0; });
}

namespace {

bool isUnsignedSmallInt(int component_type) {
  return component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
         component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
}

// Spec ("Skins"): JOINTS_n unsigned byte/short integers, WEIGHTS_n float or
// normalized unsigned byte/short. Call after the accessors have been read.
Status checkInfluenceFormat(const tinygltf::Model& model, const std::vector<int>& accessors, bool joints,
                            const std::string& role, const std::string& label) {
  for (const int index : accessors) {
    if (index < 0) continue;
    const tinygltf::Accessor& a = model.accessors[static_cast<std::size_t>(index)];
    const bool ok = joints ? isUnsignedSmallInt(a.componentType) && !a.normalized
                           : a.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                                 (isUnsignedSmallInt(a.componentType) && a.normalized);
    if (!ok) {
      return parseError(
          label, "accessor " + std::to_string(index) + " (" + role + ") must be " +
                     (joints ? "unsigned byte or short integers" : "float or normalized unsigned byte or short"));
    }
  }
  return Ok{};
}

// JOINTS_n and WEIGHTS_n of all primitives, #V by 4 each.
struct InfluenceSet {
  std::string suffix;  // "0", "1", ...
  Eigen::MatrixXd joints;
  Eigen::MatrixXd weights;
};

Result<std::vector<InfluenceSet>> readInfluenceSets(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                                    const std::vector<PrimitiveRange>& ranges,
                                                    const std::string& mesh_name, const std::string& label) {
  std::vector<InfluenceSet> sets;
  for (int n = 0;; ++n) {
    InfluenceSet set{std::to_string(n), {}, {}};
    const std::string joints_name = "JOINTS_" + set.suffix;
    const std::string weights_name = "WEIGHTS_" + set.suffix;
    const std::vector<int> joints = attributeAccessors(gmesh, joints_name);
    const std::vector<int> weights = attributeAccessors(gmesh, weights_name);
    if (!presentInAny(joints) && !presentInAny(weights)) break;
    for (std::size_t p = 0; p < joints.size(); ++p) {
      if ((joints[p] < 0) != (weights[p] < 0)) {
        return parseError(label, mesh_name + " primitive " + std::to_string(p) + " has only one of " + joints_name +
                                     " and " + weights_name);
      }
    }
    auto j = readMergedAttribute(model, joints, ranges, 4, joints_name, mesh_name, label);
    if (!j) return j.error();
    auto w = readMergedAttribute(model, weights, ranges, 4, weights_name, mesh_name, label);
    if (!w) return w.error();
    if (auto ok = checkInfluenceFormat(model, joints, true, joints_name, label); !ok) return ok.error();
    if (auto ok = checkInfluenceFormat(model, weights, false, weights_name, label); !ok) return ok.error();
    set.joints = std::move(*j);
    set.weights = std::move(*w);
    sets.push_back(std::move(set));
  }
  return sets;
}

// Skin weights (#V by #joints) from every JOINTS_n/WEIGHTS_n set: zero weights
// dropped, a joint repeated within a vertex summed, rows normalised.
Result<SkinWeights> readSkinWeights(const tinygltf::Model& model, const tinygltf::Mesh& gmesh,
                                    const std::vector<PrimitiveRange>& ranges, std::size_t joint_count,
                                    const std::string& mesh_name, const std::string& label,
                                    std::vector<std::string>& warnings) {
  auto sets = readInfluenceSets(model, gmesh, ranges, mesh_name, label);
  if (!sets) return sets.error();
  const Eigen::Index nv = vertexTotal(ranges);
  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<std::pair<int, double>> row;
  int renormalised = 0;
  int empty = 0;
  auto vertexError = [&](Eigen::Index v, const std::string& what) {
    return makeError(ErrorCode::kInvalidMesh, label + ": vertex " + std::to_string(v) + " " + what);
  };
  for (Eigen::Index v = 0; v < nv; ++v) {
    row.clear();
    for (const InfluenceSet& set : *sets) {
      for (int c = 0; c < 4; ++c) {
        const double w = set.weights(v, c);
        const double joint = set.joints(v, c);
        if (w < 0.0) return vertexError(v, "has the negative weight " + std::to_string(w) + " in WEIGHTS_" + set.suffix);
        if (w == 0.0) continue;
        if (joint >= static_cast<double>(joint_count)) {
          return vertexError(v, "uses joint " + std::to_string(static_cast<long long>(joint)) + " in JOINTS_" +
                                    set.suffix + " but the skin has " + std::to_string(joint_count) + " joints");
        }
        row.emplace_back(static_cast<int>(joint), w);
      }
    }
    std::sort(row.begin(), row.end());
    double sum = 0.0;
    for (const auto& entry : row) sum += entry.second;
    if (row.empty()) {
      ++empty;
      continue;
    }
    if (std::abs(sum - 1.0) > kWeightSumTolerance) ++renormalised;
    for (std::size_t i = 0; i < row.size(); ++i) {
      double w = row[i].second;
      while (i + 1 < row.size() && row[i + 1].first == row[i].first) w += row[++i].second;  // repeated joint
      triplets.emplace_back(static_cast<int>(v), row[i].first, w / sum);
    }
  }
  if (renormalised > 0) {
    warnings.push_back(std::to_string(renormalised) + " vertices had skin weights not summing to 1; renormalised");
  }
  if (empty > 0) {
    warnings.push_back(std::to_string(empty) + " vertices of the skinned mesh have no skin weight (left empty)");
  }
  SkinWeights weights(nv, static_cast<Eigen::Index>(joint_count));
  weights.setFromTriplets(triplets.begin(), triplets.end());
  weights.makeCompressed();
  return weights;
}

}  // namespace

Status readSkinning(const tinygltf::Model& model, const MeshChoice& choice, const std::vector<PrimitiveRange>& ranges,
                    const std::string& mesh_name, const std::string& label, Rig& rig,
                    std::vector<std::string>& warnings, const Skin* shared) {
  const tinygltf::Mesh& gmesh = model.meshes[static_cast<std::size_t>(choice.mesh)];
  if (!choice.skinned) {
    if (presentInAny(attributeAccessors(gmesh, "JOINTS_0"))) {
      warnings.push_back("JOINTS/WEIGHTS of " + mesh_name + " ignored: no node uses it with a skin");
    }
    return Ok{};
  }
  if (shared) {
    auto weights = readSkinWeights(model, gmesh, ranges, shared->joints.size(), mesh_name, label, warnings);
    if (!weights) return weights.error();
    rig.weights = std::move(*weights);
    return Ok{};
  }
  auto skin = readSkin(model, model.nodes[static_cast<std::size_t>(choice.node)].skin, label, warnings);
  if (!skin) return skin.error();
  auto weights = readSkinWeights(model, gmesh, ranges, skin->joints.size(), mesh_name, label, warnings);
  if (!weights) return weights.error();
  rig.skin = std::move(*skin);
  rig.weights = std::move(*weights);
  return Ok{};
}

}  // namespace core::gltf
