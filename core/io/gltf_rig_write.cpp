// glTF rig writing: nodes, the mesh primitives (the face and its parts),
// skin, morph targets and animations appended to one model, after checkRig
// (gltf_rig_check.cpp). encodeRigGlb.

#include "core/io/gltf_model.h"

namespace core::gltf {

Error invalidRig(const std::string& what) { return makeError(ErrorCode::kInvalidArgument, kRigLabel + ": " + what); }

namespace {

// Which output node carries the mesh. A skinned mesh's node must be an
// identity root whose TRS is not animated (glTF ignores it; the validator
// warns): the rig's node is used when it is one, reset when nothing depends
// on its transform, else a new root node is appended for the mesh.
struct MeshNodePlan {
  int node = -1;          // output node index carrying the mesh (and skin)
  bool appended = false;  // a new root node (index rig.nodes.size())
  bool reset = false;     // rig.mesh_node written as an identity root
};

bool hasTransform(const Node& node) {
  return node.translation != Eigen::Vector3d::Zero() || !node.rotation.normalized().vec().isZero(0.0) ||
         node.scale != Eigen::Vector3d::Ones();
}

bool animatesTransformOf(const Rig& rig, int node) {
  for (const Animation& animation : rig.animations) {
    for (const AnimationChannel& channel : animation.channels) {
      if (channel.node == node && channel.path != AnimationPath::kWeights) return true;
    }
  }
  return false;
}

// `mesh_node`: the node a mesh is on (the face's or a part's); a new node
// gets `appended_index`.
MeshNodePlan planMeshNode(const Rig& rig, int mesh_node, bool skinned, int appended_index) {
  if (mesh_node < 0) return {appended_index, true, false};
  if (!skinned) return {mesh_node, false, false};
  const Node& node = rig.nodes[static_cast<std::size_t>(mesh_node)];
  const bool animated = animatesTransformOf(rig, mesh_node);
  if (node.parent < 0 && !hasTransform(node) && !animated) return {mesh_node, false, false};
  const bool has_children =
      std::any_of(rig.nodes.begin(), rig.nodes.end(), [&](const Node& n) { return n.parent == mesh_node; });
  const bool is_joint =
      std::find(rig.skin->joints.begin(), rig.skin->joints.end(), mesh_node) != rig.skin->joints.end();
  if (!has_children && !is_joint && !animated) return {mesh_node, false, true};
  return {appended_index, true, false};
}

// TRS with identity components omitted.
tinygltf::Node toGltfNode(const Node& node) {
  tinygltf::Node out;
  out.name = node.name;
  const Eigen::Vector3d& t = node.translation;
  const Eigen::Quaterniond q = node.rotation.normalized();
  const Eigen::Vector3d& s = node.scale;
  if (t != Eigen::Vector3d::Zero()) out.translation = {t.x(), t.y(), t.z()};
  if (!q.vec().isZero(0.0)) out.rotation = {q.x(), q.y(), q.z(), q.w()};
  if (s != Eigen::Vector3d::Ones()) out.scale = {s.x(), s.y(), s.z()};
  return out;
}

// Where each mesh goes: the face (mesh 0) and each part (mesh 1 + p), new
// nodes numbered after the rig's in that order.
struct MeshPlacement {
  MeshNodePlan plan;
  std::string name;  // of an appended node
  bool skinned = false;
};

std::vector<MeshPlacement> planMeshNodes(const Rig& rig) {
  std::vector<MeshPlacement> out;
  int appended = static_cast<int>(rig.nodes.size());
  auto place = [&](int node, bool skinned, const std::string& name) {
    const MeshNodePlan plan = planMeshNode(rig, node, skinned, appended);
    if (plan.appended) ++appended;
    out.push_back({plan, name.empty() ? "mesh" : name, skinned});
  };
  place(rig.mesh_node, rig.skin.has_value(), rig.mesh_name);
  for (const RigPart& part : rig.parts) place(part.node, part.weights.size() > 0, part.name);
  return out;
}

// All rig nodes (children lists from the parents), the mesh nodes, one scene
// of the roots in index order.
void addRigNodes(tinygltf::Model& model, const Rig& rig, const std::vector<MeshPlacement>& meshes) {
  const int n = static_cast<int>(rig.nodes.size());
  for (const Node& node : rig.nodes) model.nodes.push_back(toGltfNode(node));
  std::vector<char> reset(rig.nodes.size(), 0);
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    const MeshNodePlan& plan = meshes[m].plan;
    if (plan.appended) {
      tinygltf::Node mesh_node;
      mesh_node.name = meshes[m].name;
      model.nodes.push_back(std::move(mesh_node));
    }
    tinygltf::Node& mesh_node = model.nodes[static_cast<std::size_t>(plan.node)];
    if (plan.reset) {
      mesh_node.translation.clear();
      mesh_node.rotation.clear();
      mesh_node.scale.clear();
      reset[static_cast<std::size_t>(plan.node)] = 1;
    }
    mesh_node.mesh = static_cast<int>(m);
    if (meshes[m].skinned) mesh_node.skin = 0;
  }
  tinygltf::Scene scene;
  for (int i = 0; i < n; ++i) {
    const int parent = reset[static_cast<std::size_t>(i)] ? -1 : rig.nodes[static_cast<std::size_t>(i)].parent;
    if (parent < 0) {
      scene.nodes.push_back(i);
    } else {
      model.nodes[static_cast<std::size_t>(parent)].children.push_back(i);
    }
  }
  for (int i = n; i < static_cast<int>(model.nodes.size()); ++i) scene.nodes.push_back(i);
  model.scenes.push_back(std::move(scene));
  // tinygltf writes a node with no property as null, which no reader accepts.
  for (tinygltf::Node& node : model.nodes) {
    const bool empty = node.name.empty() && node.translation.empty() && node.rotation.empty() && node.scale.empty() &&
                       node.children.empty() && node.mesh < 0;
    if (empty) node.translation = {0.0, 0.0, 0.0};
  }
  model.defaultScene = 0;
}

// World space -> the mesh node's space. The reader moves an unskinned mesh
// into world space by its node (placeMesh), so the writer moves it back;
// skinned meshes and meshes on a new root node need nothing.
struct NodeSpace {
  bool identity = true;
  Eigen::Matrix3d linear = Eigen::Matrix3d::Identity();          // node -> world
  Eigen::Matrix3d inverse_linear = Eigen::Matrix3d::Identity();  // world -> node
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::MatrixX3d points(const Eigen::MatrixX3d& p) const {
    return identity ? p : Eigen::MatrixX3d((p.rowwise() - translation.transpose()) * inverse_linear.transpose());
  }
  Eigen::MatrixX3d vectors(const Eigen::MatrixX3d& d) const {
    return identity ? d : Eigen::MatrixX3d(d * inverse_linear.transpose());
  }
  Eigen::MatrixX3d normals(const Eigen::MatrixX3d& n) const { return identity ? n : Eigen::MatrixX3d(n * linear); }
};

Result<NodeSpace> meshNodeSpace(const Rig& rig, const MeshNodePlan& plan) {
  NodeSpace space;
  if (rig.skin || plan.appended) return space;
  const Eigen::Matrix4d world = nodeWorldTransforms(rig.nodes)[static_cast<std::size_t>(plan.node)];
  if (world.isIdentity(0.0)) return space;
  space.identity = false;
  space.linear = world.topLeftCorner<3, 3>();
  space.translation = world.topRightCorner<3, 1>();
  const double det = space.linear.determinant();
  if (!(std::abs(det) > 0.0) || !std::isfinite(det)) {
    return invalidRig("the world transform of mesh " + nodeName(rig, plan.node) + " is singular");
  }
  space.inverse_linear = space.linear.inverse();
  return space;
}

Mesh meshInNodeSpace(const Mesh& mesh, const NodeSpace& space) {
  Mesh local = mesh;
  local.positions = space.points(mesh.positions);
  if (mesh.normals.rows() > 0) local.normals = space.normals(mesh.normals);
  if (space.linear.determinant() < 0.0) local.triangles.col(1).swap(local.triangles.col(2));  // as the reader flips
  return local;
}

// Per vertex, the kept influences: `slots` (4 or 8) (joint, weight) pairs,
// largest weight first (ties: lower joint), summing to 1; unused slots are
// joint 0 weight 0.
struct InfluenceTable {
  int slots = 4;
  std::vector<int> joints;      // #V * slots
  std::vector<double> weights;  // #V * slots
};

Result<InfluenceTable> selectInfluences(const SkinWeights& weights, int max_influences) {
  const auto nv = static_cast<std::size_t>(weights.rows());
  std::vector<std::vector<std::pair<int, double>>> kept(nv);
  int widest = 0;
  std::vector<std::pair<int, double>> row;
  for (std::size_t v = 0; v < nv; ++v) {
    row.clear();
    for (SkinWeights::InnerIterator it(weights, static_cast<Eigen::Index>(v)); it; ++it) {
      const double w = it.value();
      if (!std::isfinite(w) || w < 0.0) {
        return invalidRig("vertex " + std::to_string(v) + " has weight " + std::to_string(w) + " on joint " +
                          std::to_string(it.col()) + " (weights must be finite and >= 0)");
      }
      if (w > 0.0) row.emplace_back(static_cast<int>(it.col()), w);
    }
    if (row.empty()) return invalidRig("vertex " + std::to_string(v) + " of the skinned mesh has no skin weight");
    std::sort(row.begin(), row.end(), [](const auto& a, const auto& b) {
      return a.second != b.second ? a.second > b.second : a.first < b.first;
    });
    if (row.size() > static_cast<std::size_t>(max_influences)) row.resize(static_cast<std::size_t>(max_influences));
    double sum = 0.0;
    for (const auto& entry : row) sum += entry.second;
    for (auto& entry : row) entry.second /= sum;
    widest = std::max(widest, static_cast<int>(row.size()));
    kept[v] = row;
  }
  InfluenceTable table;
  table.slots = widest > 4 ? 8 : 4;
  const auto slots = static_cast<std::size_t>(table.slots);
  table.joints.assign(nv * slots, 0);
  table.weights.assign(nv * slots, 0.0);
  for (std::size_t v = 0; v < nv; ++v) {
    for (std::size_t s = 0; s < kept[v].size(); ++s) {
      table.joints[v * slots + s] = kept[v][s].first;
      table.weights[v * slots + s] = kept[v][s].second;
    }
  }
  return table;
}

// The validator's sum of one vertex's weights: float32, component-major
// across the JOINTS_n/WEIGHTS_n sets (gltf-validator's eX.dY).
float validatorWeightSum(const float* w, int slots) {
  float sum = 0.0f;
  for (int c = 0; c < 4; ++c) {
    for (int set = 0; set < slots / 4; ++set) sum += w[set * 4 + c];
  }
  return sum;
}

// Float weights whose float32 sum is 1 (the largest absorbs the rounding).
std::vector<float> encodeFloatWeights(const InfluenceTable& table, std::vector<int>& joints) {
  std::vector<float> out(table.weights.size());
  const auto slots = static_cast<std::size_t>(table.slots);
  for (std::size_t base = 0; base < out.size(); base += slots) {
    for (std::size_t s = 0; s < slots; ++s) out[base + s] = static_cast<float>(table.weights[base + s]);
    for (int pass = 0; pass < 4 && validatorWeightSum(&out[base], table.slots) != 1.0f; ++pass) {
      double sum = 0.0;
      for (std::size_t s = 0; s < slots; ++s) sum += out[base + s];
      out[base] = static_cast<float>(out[base] + (1.0 - sum));
    }
    for (std::size_t s = 0; s < slots; ++s) {
      if (out[base + s] == 0.0f) joints[base + s] = 0;  // underflowed: an unused slot
    }
  }
  return out;
}

// Normalized integer weights summing exactly to `scale` per vertex
// (largest-remainder rounding; ties: earlier slot, i.e. larger weight).
template <typename T>
std::vector<T> quantizeWeights(const InfluenceTable& table, std::uint32_t scale, std::vector<int>& joints) {
  std::vector<T> out(table.weights.size(), 0);
  const auto slots = static_cast<std::size_t>(table.slots);
  std::vector<std::pair<double, std::size_t>> remainders;
  for (std::size_t base = 0; base < out.size(); base += slots) {
    std::uint32_t total = 0;
    remainders.clear();
    for (std::size_t s = 0; s < slots; ++s) {
      const double exact = table.weights[base + s] * scale;
      const double floor = std::min(std::floor(exact), static_cast<double>(scale));
      out[base + s] = static_cast<T>(floor);
      total += static_cast<std::uint32_t>(floor);
      if (table.weights[base + s] > 0.0) remainders.emplace_back(exact - floor, s);
    }
    std::stable_sort(remainders.begin(), remainders.end(),
                     [](const auto& a, const auto& b) { return a.first > b.first; });
    for (std::size_t i = 0; total < scale && !remainders.empty(); i = (i + 1) % remainders.size(), ++total) {
      ++out[base + remainders[i].second];
    }
    for (std::size_t s = 0; s < slots; ++s) {
      if (out[base + s] == 0) joints[base + s] = 0;  // rounded away: an unused slot
    }
  }
  return out;
}

// Elements [4 * set, 4 * set + 4) of every vertex's `slots` values.
template <typename T, typename U>
std::vector<T> influenceSet(const std::vector<U>& values, int slots, int set) {
  std::vector<T> out;
  out.reserve(values.size() / static_cast<std::size_t>(slots) * 4);
  for (std::size_t base = 0; base < values.size(); base += static_cast<std::size_t>(slots)) {
    for (int c = 0; c < 4; ++c) out.push_back(static_cast<T>(values[base + static_cast<std::size_t>(set * 4 + c)]));
  }
  return out;
}

// JOINTS_n (unsigned byte below 256 joints, else short) for each set.
void addJointSets(tinygltf::Model& model, const std::vector<int>& joints, int slots, std::size_t joint_count,
                  tinygltf::Primitive& primitive) {
  const std::size_t nv = joints.size() / static_cast<std::size_t>(slots);
  for (int set = 0; set < slots / 4; ++set) {
    int view = 0;
    int type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    if (joint_count <= 256) {
      view =
          addBufferView(model, asBytes(influenceSet<std::uint8_t>(joints, slots, set)), TINYGLTF_TARGET_ARRAY_BUFFER);
    } else {
      view =
          addBufferView(model, asBytes(influenceSet<std::uint16_t>(joints, slots, set)), TINYGLTF_TARGET_ARRAY_BUFFER);
      type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    }
    primitive.attributes["JOINTS_" + std::to_string(set)] = addAccessor(model, view, type, TINYGLTF_TYPE_VEC4, nv);
  }
}

// WEIGHTS_n in the chosen encoding; zeroes the joints of slots left empty.
void addWeightSets(tinygltf::Model& model, const InfluenceTable& table, WeightEncoding encoding,
                   std::vector<int>& joints, tinygltf::Primitive& primitive) {
  const std::size_t nv = joints.size() / static_cast<std::size_t>(table.slots);
  std::vector<float> floats;
  std::vector<std::uint16_t> shorts;
  std::vector<std::uint8_t> bytes;
  if (encoding == WeightEncoding::kFloat) floats = encodeFloatWeights(table, joints);
  if (encoding == WeightEncoding::kUnorm16) shorts = quantizeWeights<std::uint16_t>(table, 65535, joints);
  if (encoding == WeightEncoding::kUnorm8) bytes = quantizeWeights<std::uint8_t>(table, 255, joints);
  for (int set = 0; set < table.slots / 4; ++set) {
    int view = 0;
    int type = TINYGLTF_COMPONENT_TYPE_FLOAT;
    if (encoding == WeightEncoding::kFloat) {
      view = addBufferView(model, asBytes(influenceSet<float>(floats, table.slots, set)), TINYGLTF_TARGET_ARRAY_BUFFER);
    } else if (encoding == WeightEncoding::kUnorm16) {
      view = addBufferView(model, asBytes(influenceSet<std::uint16_t>(shorts, table.slots, set)),
                           TINYGLTF_TARGET_ARRAY_BUFFER);
      type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    } else {
      view = addBufferView(model, asBytes(influenceSet<std::uint8_t>(bytes, table.slots, set)),
                           TINYGLTF_TARGET_ARRAY_BUFFER);
      type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    }
    const int accessor = addAccessor(model, view, type, TINYGLTF_TYPE_VEC4, nv);
    model.accessors[static_cast<std::size_t>(accessor)].normalized = encoding != WeightEncoding::kFloat;
    primitive.attributes["WEIGHTS_" + std::to_string(set)] = accessor;
  }
}

// Inverse bind matrices as a MAT4 float accessor, bottom rows exactly 0 0 0 1.
int addInverseBinds(tinygltf::Model& model, const Skin& skin) {
  std::vector<float> values;
  values.reserve(skin.inverse_bind.size() * 16);
  for (const Eigen::Matrix4d& m : skin.inverse_bind) {
    for (int c = 0; c < 4; ++c) {
      for (int r = 0; r < 3; ++r) values.push_back(static_cast<float>(m(r, c)));
      values.push_back(c == 3 ? 1.0f : 0.0f);
    }
  }
  return addFloatAccessor(model, values, TINYGLTF_TYPE_MAT4, /*target=*/0, false);
}

// JOINTS_n / WEIGHTS_n of one mesh of the rig (its weights by the skin's joints).
Status addInfluences(tinygltf::Model& model, const SkinWeights& weights, std::size_t joint_count,
                     const RigWriteOptions& options, tinygltf::Primitive& primitive) {
  auto table = selectInfluences(weights, options.max_influences);
  if (!table) return table.error();
  std::vector<int> joints = table->joints;
  addWeightSets(model, *table, options.weight_encoding, joints, primitive);  // before the joints: may zero some
  addJointSets(model, joints, table->slots, joint_count, primitive);
  return Ok{};
}

// The face's influences and the rig's one skin (skin 0, shared by the parts).
Status addSkin(tinygltf::Model& model, const Rig& rig, const RigWriteOptions& options, tinygltf::Primitive& primitive) {
  if (auto ok = addInfluences(model, rig.weights, rig.skin->joints.size(), options, primitive); !ok) return ok.error();
  tinygltf::Skin skin;
  skin.name = rig.skin->name;
  skin.joints = rig.skin->joints;
  skin.skeleton = rig.skin->skeleton;
  skin.inverseBindMatrices = addInverseBinds(model, *rig.skin);
  model.skins.push_back(std::move(skin));
  return Ok{};
}

// A morph delta accessor (#V VEC3 floats): sparse (the rows with a non-zero
// component) when `sparse` and smaller than dense, with no data at all when
// every row is zero. `bounds` sets min/max over all rows, the implicit zeros
// included (the validator requires them for POSITION deltas).
int addDeltaAccessor(tinygltf::Model& model, const std::vector<float>& deltas, bool sparse, bool bounds) {
  const std::size_t count = deltas.size() / 3;
  if (!sparse) return addFloatAccessor(model, deltas, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, bounds);
  // Which rows move, without a branch per row (moving and still rows
  // alternate unpredictably; mispredicted compares were most of the GLB
  // encode): a row moves when a component other than +-0 is in it.
  std::vector<std::uint32_t> moves(count);
  std::size_t moving = 0;
  for (std::size_t r = 0; r < count; ++r) {
    const std::uint32_t any = (std::bit_cast<std::uint32_t>(deltas[3 * r]) | std::bit_cast<std::uint32_t>(deltas[3 * r + 1]) |
                               std::bit_cast<std::uint32_t>(deltas[3 * r + 2])) &
                              0x7fffffffu;
    moves[r] = any != 0 ? 1u : 0u;
    moving += moves[r];
  }
  const bool short_indices = count <= 65536;
  const std::size_t index_size = short_indices ? 2 : 4;
  if (moving * (index_size + 12) >= count * 12) {
    return addFloatAccessor(model, deltas, TINYGLTF_TYPE_VEC3, TINYGLTF_TARGET_ARRAY_BUFFER, bounds);
  }
  // Compacted the same way: every row is written at the next free slot, which
  // only a moving row keeps (one spare slot for the last still rows).
  std::vector<std::uint32_t> rows(moving + 1);
  std::vector<float> values(3 * (moving + 1));
  for (std::size_t r = 0, k = 0; r < count; ++r) {
    rows[k] = static_cast<std::uint32_t>(r);
    std::copy_n(deltas.begin() + static_cast<std::ptrdiff_t>(3 * r), 3, values.begin() + static_cast<std::ptrdiff_t>(3 * k));
    k += moves[r];
    if (k == moving) break;  // the rest are still (and there is no slot past the spare)
  }
  rows.resize(moving);
  values.resize(3 * moving);
  std::vector<double> min;
  std::vector<double> max;
  if (bounds) std::tie(min, max) = floatBounds(deltas, 3);
  const int accessor = addAccessor(model, -1, TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_TYPE_VEC3, count, min, max);
  if (rows.empty()) return accessor;  // no bufferView, no sparse: all zeros
  const int index_view = short_indices
                             ? addBufferView(model, asBytes(std::vector<std::uint16_t>(rows.begin(), rows.end())), 0)
                             : addBufferView(model, asBytes(rows), 0);
  const int value_view = addBufferView(model, asBytes(values), 0);
  auto& s = model.accessors[static_cast<std::size_t>(accessor)].sparse;
  s.isSparse = true;
  s.count = static_cast<int>(rows.size());
  s.indices.bufferView = index_view;
  s.indices.byteOffset = 0;
  s.indices.componentType =
      short_indices ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  s.values.bufferView = value_view;
  s.values.byteOffset = 0;
  return accessor;
}

// Morph targets, their names (mesh.extras.targetNames) and default weights.
Status addMorphTargets(tinygltf::Model& model, const Rig& rig, const NodeSpace& space, bool sparse,
                       tinygltf::Primitive& primitive, tinygltf::Mesh& gmesh) {
  if (rig.morph_targets.empty()) return Ok{};
  tinygltf::Value::Array names;
  for (std::size_t t = 0; t < rig.morph_targets.size(); ++t) {
    const MorphTarget& target = rig.morph_targets[t];
    const std::string what = "morph target " + std::to_string(t) + quoted(target.name);
    const std::vector<float> positions = toFloats(space.vectors(target.position_deltas));
    if (const auto bad = firstNonFinite(positions)) {
      return invalidRig(what + " position delta of vertex " + std::to_string(*bad / 3) + " is not finite in float32");
    }
    std::map<std::string, int> attributes;
    attributes["POSITION"] = addDeltaAccessor(model, positions, sparse, /*bounds=*/true);
    if (target.normal_deltas.rows() > 0) {
      const std::vector<float> normals = toFloats(space.normals(target.normal_deltas));
      if (const auto bad = firstNonFinite(normals)) {
        return invalidRig(what + " normal delta of vertex " + std::to_string(*bad / 3) + " is not finite in float32");
      }
      attributes["NORMAL"] = addDeltaAccessor(model, normals, sparse, /*bounds=*/false);
    }
    primitive.targets.push_back(std::move(attributes));
    names.emplace_back(target.name);
  }
  const Eigen::VectorXd& defaults = rig.morph_default_weights;
  gmesh.weights.assign(rig.morph_targets.size(), 0.0);
  for (Eigen::Index t = 0; t < defaults.size(); ++t) gmesh.weights[static_cast<std::size_t>(t)] = defaults(t);
  tinygltf::Value::Object extras;
  extras["targetNames"] = tinygltf::Value(std::move(names));
  if (!rig.baked_presets.empty()) {
    tinygltf::Value::Array baked;
    for (const std::string& name : rig.baked_presets) baked.emplace_back(name);
    extras[kBakedPresetsKey] = tinygltf::Value(std::move(baked));
  }
  gmesh.extras = tinygltf::Value(std::move(extras));
  return Ok{};
}

const char* pathName(AnimationPath path) {
  switch (path) {
    case AnimationPath::kTranslation: return "translation";
    case AnimationPath::kRotation: return "rotation";
    case AnimationPath::kScale: return "scale";
    case AnimationPath::kWeights: return "weights";
  }
  return "translation";
}

const char* interpolationName(Interpolation interpolation) {
  switch (interpolation) {
    case Interpolation::kLinear: return "LINEAR";
    case Interpolation::kStep: return "STEP";
    case Interpolation::kCubicSpline: return "CUBICSPLINE";
  }
  return "LINEAR";
}

// Key times as a float SCALAR accessor with min/max (spec), shared between
// channels with the same times.
Result<int> addKeyTimes(tinygltf::Model& model, const Eigen::VectorXd& times, const std::string& what,
                        std::map<std::vector<float>, int>& shared) {
  if (times.size() == 0) return invalidRig(what + " has no keys");
  std::vector<float> t = toFloats(times);
  for (std::size_t k = 0; k < t.size(); ++k) {
    if (!std::isfinite(t[k]) || t[k] < 0.0f) {
      return invalidRig(what + " key time " + std::to_string(k) + " is negative or not finite");
    }
    if (k > 0 && !(t[k] > t[k - 1])) {
      return invalidRig(what + " key times do not increase (in float32) at key " + std::to_string(k));
    }
  }
  const auto it = shared.find(t);
  if (it != shared.end()) return it->second;
  const int accessor = addFloatAccessor(model, t, TINYGLTF_TYPE_SCALAR, /*target=*/0, /*bounds=*/true);
  shared.emplace(std::move(t), accessor);
  return accessor;
}

// Output values: VEC3 (translation, scale), unit VEC4 (rotation; cubic
// tangents as they are) or #targets scalars per key (weights).
Result<int> addKeyValues(tinygltf::Model& model, const AnimationChannel& channel, int columns,
                         const std::string& what) {
  const bool cubic = channel.interpolation == Interpolation::kCubicSpline;
  const Eigen::Index rows = channel.times.size() * (cubic ? 3 : 1);
  if (channel.values.rows() != rows || channel.values.cols() != columns) {
    return invalidRig(what + " values are " + std::to_string(channel.values.rows()) + " by " +
                      std::to_string(channel.values.cols()) + ", expected " + std::to_string(rows) + " by " +
                      std::to_string(columns));
  }
  std::vector<float> values = toFloats(channel.values);
  if (const auto bad = firstNonFinite(values)) {
    return invalidRig(what + " value " + std::to_string(*bad / static_cast<std::size_t>(columns)) +
                      " is not finite in float32");
  }
  if (channel.path == AnimationPath::kRotation) {
    for (Eigen::Index r = cubic ? 1 : 0; r < rows; r += cubic ? 3 : 1) {
      const Eigen::Vector4d q = channel.values.row(r).transpose();
      if (!(q.norm() > 0.0)) return invalidRig(what + " rotation key " + std::to_string(r) + " is a zero quaternion");
      for (int c = 0; c < 4; ++c) values[static_cast<std::size_t>(r * 4 + c)] = static_cast<float>(q(c) / q.norm());
    }
  }
  const int type = channel.path == AnimationPath::kWeights    ? TINYGLTF_TYPE_SCALAR
                   : channel.path == AnimationPath::kRotation ? TINYGLTF_TYPE_VEC4
                                                              : TINYGLTF_TYPE_VEC3;
  return addFloatAccessor(model, values, type, /*target=*/0, false);
}

// Output node of a channel (weights go to the node carrying their mesh) and
// its value columns.
struct ChannelTarget {
  int node = -1;
  int columns = 3;
};

Result<ChannelTarget> channelTarget(const Rig& rig, const AnimationChannel& channel,
                                    const std::vector<MeshPlacement>& meshes, const std::string& what) {
  if (channel.node < 0 || static_cast<std::size_t>(channel.node) >= rig.nodes.size()) {
    return invalidRig(what + " targets node " + std::to_string(channel.node) + " but the rig has " +
                      std::to_string(rig.nodes.size()) + " nodes");
  }
  if (channel.path == AnimationPath::kRotation) return ChannelTarget{channel.node, 4};
  if (channel.path != AnimationPath::kWeights) return ChannelTarget{channel.node, 3};
  std::size_t targets = 0;
  int mesh = -1;
  if (channel.node == rig.mesh_node) {
    mesh = 0;
    targets = rig.morph_targets.size();
  }
  for (std::size_t p = 0; p < rig.parts.size() && mesh < 0; ++p) {
    if (rig.parts[p].node != channel.node) continue;
    mesh = static_cast<int>(p) + 1;
    targets = rig.parts[p].morph_targets.size();
  }
  if (mesh < 0 || targets == 0) {
    return invalidRig(what + " animates morph weights of " + nodeName(rig, channel.node) +
                      ", which does not carry a morphed mesh of the rig");
  }
  return ChannelTarget{meshes[static_cast<std::size_t>(mesh)].plan.node, static_cast<int>(targets)};
}

Status addAnimation(tinygltf::Model& model, const Rig& rig, const Animation& animation, const std::string& name,
                    const std::vector<MeshPlacement>& meshes, std::map<std::vector<float>, int>& shared_times) {
  tinygltf::Animation ganim;
  ganim.name = animation.name;
  std::set<std::pair<int, AnimationPath>> targets;
  for (std::size_t c = 0; c < animation.channels.size(); ++c) {
    const AnimationChannel& channel = animation.channels[c];
    const std::string what = name + " channel " + std::to_string(c);
    auto target = channelTarget(rig, channel, meshes, what);
    if (!target) return target.error();
    if (!targets.emplace(target->node, channel.path).second) {
      return invalidRig(what + " animates the same node and path as an earlier channel");
    }
    auto input = addKeyTimes(model, channel.times, what, shared_times);
    if (!input) return input.error();
    auto output = addKeyValues(model, channel, target->columns, what);
    if (!output) return output.error();
    tinygltf::AnimationSampler sampler;
    sampler.input = *input;
    sampler.output = *output;
    sampler.interpolation = interpolationName(channel.interpolation);
    ganim.samplers.push_back(std::move(sampler));
    tinygltf::AnimationChannel gchannel;
    gchannel.sampler = static_cast<int>(ganim.samplers.size()) - 1;
    gchannel.target_node = target->node;
    gchannel.target_path = pathName(channel.path);
    ganim.channels.push_back(std::move(gchannel));
  }
  model.animations.push_back(std::move(ganim));
  return Ok{};
}

// Animations with channels (tinygltf drops empty ones; so do we).
Status addAnimations(tinygltf::Model& model, const Rig& rig, const std::vector<MeshPlacement>& meshes) {
  std::map<std::vector<float>, int> shared_times;
  for (std::size_t a = 0; a < rig.animations.size(); ++a) {
    const Animation& animation = rig.animations[a];
    if (animation.channels.empty()) continue;
    const std::string name = "animation " + std::to_string(a) + quoted(animation.name);
    if (auto ok = addAnimation(model, rig, animation, name, meshes, shared_times); !ok) return ok.error();
  }
  return Ok{};
}

// Bytes the rig's buffer takes at most for usual rigs (morph targets dense,
// every attribute written, fields of up to 4 components): reserved once so
// appending does not re-copy the buffer. Only a capacity hint: a rig beyond
// it costs one reallocation; untouched reserve costs address space, not memory.
std::size_t rigBufferBound(const Rig& rig) {
  const auto nv = static_cast<std::size_t>(rig.mesh.vertexCount());
  std::size_t per_vertex = 3 * 12 + 2 * 8 + 2 * 16 * 4;  // position, normal, UVs, joints/weights (up to 2 sets)
  per_vertex += 16 * (rig.attributes.extra_uv_sets.size() + rig.attributes.fields.size() + rig.attributes.labels.size() + 1);
  std::size_t bytes = nv * per_vertex + static_cast<std::size_t>(rig.mesh.triangleCount()) * 12;
  for (const TextureImage& image : rig.images) bytes += image.bytes.size() + 4;
  for (const auto& t : rig.morph_targets) bytes += nv * 12 * (t.normal_deltas.rows() > 0 ? 2 : 1) + 64;
  for (const auto& a : rig.animations) {
    for (const auto& c : a.channels) bytes += static_cast<std::size_t>(c.values.size() + c.times.size()) * 4 + 64;
  }
  return bytes + 64 * (rig.nodes.size() + 1);
}

// One mesh of the rig (the face, or a part seen as a rig: partAsRig) with its
// attributes, influences and morph targets; the first one written adds the skin.
Status addRigMesh(tinygltf::Model& model, const Rig& rig, const MeshNodePlan& plan, const RigWriteOptions& options,
                  bool first) {
  auto space = meshNodeSpace(rig, plan);
  if (!space) return space.error();
  std::optional<Mesh> local;
  if (!space->identity) local = meshInNodeSpace(rig.mesh, *space);
  const bool split = !rig.triangle_materials.empty();
  auto primitive = addMeshPrimitive(model, local ? *local : rig.mesh, kRigLabel, /*with_indices=*/!split);
  if (!primitive) return primitive.error();
  if (auto ok = addVertexAttributes(model, rig, *primitive); !ok) return ok.error();
  if (rig.skin && first) {
    if (auto ok = addSkin(model, rig, options, *primitive); !ok) return ok.error();
  } else if (rig.skin) {
    if (auto ok = addInfluences(model, rig.weights, rig.skin->joints.size(), options, *primitive); !ok) return ok.error();
  }
  tinygltf::Mesh gmesh;
  gmesh.name = rig.mesh_name;
  if (auto ok = addMorphTargets(model, rig, *space, options.sparse_morph_targets, *primitive, gmesh); !ok) {
    return ok.error();
  }
  if (split) {
    gmesh.primitives = splitByMaterial(model, *primitive, rig.mesh, rig.triangle_materials);
  } else {
    gmesh.primitives.push_back(std::move(*primitive));
  }
  model.meshes.push_back(std::move(gmesh));
  return Ok{};
}

Result<tinygltf::Model> buildRigModel(const Rig& rig, const RigWriteOptions& options) {
  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "rigport";
  model.buffers.emplace_back();
  model.buffers[0].data.reserve(rigBufferBound(rig));
  addMaterials(model, rig);
  const std::vector<MeshPlacement> meshes = planMeshNodes(rig);
  if (auto ok = addRigMesh(model, rig, meshes[0].plan, options, /*first=*/true); !ok) return ok.error();
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    const Rig view = partAsRig(rig, rig.parts[p]);
    if (auto ok = addRigMesh(model, view, meshes[p + 1].plan, options, /*first=*/false); !ok) {
      return makeError(ok.error().code, "part " + std::to_string(p) + quoted(rig.parts[p].name) + ": " + ok.error().message);
    }
  }
  addRigNodes(model, rig, meshes);
  if (auto ok = addAnimations(model, rig, meshes); !ok) return ok.error();
  return model;
}

}  // namespace

}  // namespace core::gltf

namespace core {

Result<std::vector<std::uint8_t>> encodeRigGlb(const Rig& rig, const RigWriteOptions& options) {
  if (auto ok = gltf::checkRig(rig, options); !ok) return ok.error();
  auto model = gltf::buildRigModel(rig, options);
  if (!model) return model.error();
  return gltf::serializeGlb(*model);
}

Status writeRigGlb(const Rig& rig, const std::filesystem::path& path, const RigWriteOptions& options) {
  auto bytes = encodeRigGlb(rig, options);
  if (!bytes) return makeError(bytes.error().code, path.filename().string() + ": " + bytes.error().message);
  return writeFileBytes(path, *bytes);
}

}  // namespace core
