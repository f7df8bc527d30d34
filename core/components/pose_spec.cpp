// The pose JSON (parsePoseSpec) and a rig posed by it (poseRig): see
// pose_spec.h. nlohmann::json is used privately here (file format edge);
// nothing JSON leaves this file.
#include "core/components/pose_spec.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <nlohmann/json.hpp>

#include "core/components/cluster.h"
#include "core/components/pose.h"
#include "core/geometry/mesh.h"
#include "core/geometry/point_cloud_index.h"
#include "core/io/json_text.h"
#include "core/io/mesh_io.h"
#include "core/rig/skinning.h"

namespace core {

namespace {

constexpr std::array<const char*, 4> kPoseKeys = {"preset", "controls", "morph_weights", "joints"};

Error fieldError(const std::string& label, const std::string& field, const std::string& what) {
  return makeError(ErrorCode::kInvalidArgument, label + ": " + field + ": " + what);
}

Result<double> readFinite(const nlohmann::json& value, const std::string& label, const std::string& field) {
  if (!value.is_number()) return fieldError(label, field, "must be a number");
  const double number = value.get<double>();
  if (!std::isfinite(number)) return fieldError(label, field, "must be a finite number");
  return number;
}

// {"name": number, ...} of `field`.
Result<std::map<std::string, double>> readNumberMap(const nlohmann::json& value, const std::string& label,
                                                    const std::string& field) {
  if (!value.is_object()) return fieldError(label, field, "must be an object of name: number");
  std::map<std::string, double> out;
  for (const auto& [name, number] : value.items()) {
    if (name.empty()) return fieldError(label, field, "an empty name");
    auto read = readFinite(number, label, field + "." + name);
    if (!read) return read.error();
    out[name] = *read;
  }
  return out;
}

// {"joint": [x, y, z], ...}: Euler degrees.
Result<std::map<std::string, Eigen::Vector3d>> readRotationMap(const nlohmann::json& value, const std::string& label,
                                                               const std::string& field) {
  if (!value.is_object()) return fieldError(label, field, "must be an object of joint name: [x, y, z] degrees");
  std::map<std::string, Eigen::Vector3d> out;
  for (const auto& [name, angles] : value.items()) {
    const std::string where = field + "." + name;
    if (name.empty()) return fieldError(label, field, "an empty joint name");
    if (!angles.is_array() || angles.size() != 3) return fieldError(label, where, "must be [x, y, z] (Euler degrees)");
    Eigen::Vector3d degrees;
    for (int k = 0; k < 3; ++k) {
      auto read = readFinite(angles[static_cast<std::size_t>(k)], label, where + "[" + std::to_string(k) + "]");
      if (!read) return read.error();
      degrees(k) = *read;
    }
    out[name] = degrees;
  }
  return out;
}

}  // namespace

Result<PoseSpec> parsePoseSpec(std::string_view json_text, const std::string& label) {
  auto parsed = parseJsonText(json_text, label, "pose JSON");
  if (!parsed) return parsed.error();
  const nlohmann::json& doc = *parsed;
  if (!doc.is_object()) {
    return makeError(ErrorCode::kInvalidArgument,
                     label + ": expected a JSON object with any of \"preset\", \"controls\", \"morph_weights\", \"joints\"");
  }
  PoseSpec spec;
  for (const auto& [key, value] : doc.items()) {
    if (key == "preset") {
      if (!value.is_string() || value.get<std::string>().empty()) {
        return fieldError(label, key, "must be a non-empty string (a preset name)");
      }
      spec.preset = value.get<std::string>();
    } else if (key == "controls" || key == "morph_weights") {
      auto read = readNumberMap(value, label, key);
      if (!read) return read.error();
      (key == "controls" ? spec.controls : spec.morph_weights) = std::move(*read);
    } else if (key == "joints") {
      auto read = readRotationMap(value, label, key);
      if (!read) return read.error();
      spec.joint_rotations = std::move(*read);
    } else {
      return fieldError(label, key, "unknown key" + didYouMean(key, {kPoseKeys.begin(), kPoseKeys.end()}) +
                                        "; known: " + joinNames({kPoseKeys.begin(), kPoseKeys.end()}));
    }
  }
  return spec;
}

Result<PoseSpec> readPoseSpec(const std::filesystem::path& path) {
  auto bytes = readFileBytes(path);
  if (!bytes) return bytes.error();
  return parsePoseSpec(std::string(bytes->begin(), bytes->end()), path.filename().string());
}

namespace {

// Morph target names of the face, then of each part, each once.
std::vector<std::string> morphTargetNames(const Rig& rig) {
  std::vector<std::string> names;
  auto add = [&](const std::vector<MorphTarget>& targets) {
    for (const MorphTarget& target : targets) {
      if (std::find(names.begin(), names.end(), target.name) == names.end()) names.push_back(target.name);
    }
  };
  add(rig.morph_targets);
  for (const RigPart& part : rig.parts) add(part.morph_targets);
  return names;
}

// Node index by name; the first node of a repeated name.
std::map<std::string, int> nodeIndexByName(const std::vector<Node>& nodes) {
  std::map<std::string, int> index;
  for (std::size_t n = 0; n < nodes.size(); ++n) {
    if (!nodes[n].name.empty()) index.emplace(nodes[n].name, static_cast<int>(n));
  }
  return index;
}

std::vector<std::string> keysOf(const std::map<std::string, int>& map) {
  std::vector<std::string> keys;
  for (const auto& [key, value] : map) keys.push_back(key);
  return keys;
}

// Every name the spec gives is the rig's or its document's.
Status checkSpecNames(const Rig& rig, const ComponentsDocument* doc, const PoseSpec& spec, const PoseLabels& labels) {
  const std::string in_components = " in " + labels.components;
  if (!doc && !spec.preset.empty()) return fieldError(labels.pose, "preset", "needs a components document (none given)");
  if (!doc && !spec.controls.empty()) return fieldError(labels.pose, "controls", "need a components document (none given)");
  if (doc && !spec.preset.empty() && !doc->presets.count(spec.preset)) {
    std::vector<std::string> presets;
    for (const auto& [name, preset] : doc->presets) presets.push_back(name);
    return fieldError(labels.pose, "preset", "unknown preset \"" + spec.preset + "\"" + in_components +
                                                 didYouMean(spec.preset, presets) +
                                                 (presets.empty() ? " (it has none)" : ""));
  }
  for (const auto& [name, value] : spec.controls) {
    if (indexByName(doc->controls, name) >= 0) continue;
    std::vector<std::string> controls;
    for (const Control& control : doc->controls) controls.push_back(control.name);
    return fieldError(labels.pose, "controls." + name,
                      "unknown control \"" + name + "\"" + in_components + didYouMean(name, controls));
  }
  const std::vector<std::string> targets = morphTargetNames(rig);
  for (const auto& [name, weight] : spec.morph_weights) {
    if (std::find(targets.begin(), targets.end(), name) != targets.end()) continue;
    return fieldError(labels.pose, "morph_weights." + name,
                      "the rig has no morph target \"" + name + "\"" + didYouMean(name, targets) +
                          (targets.empty() ? " (it has none)" : ""));
  }
  const std::map<std::string, int> nodes = nodeIndexByName(rig.nodes);
  for (const auto& [name, degrees] : spec.joint_rotations) {
    if (nodes.count(name)) continue;
    return fieldError(labels.pose, "joints." + name,
                      "the rig has no joint (node) \"" + name + "\"" + didYouMean(name, keysOf(nodes)));
  }
  return Ok{};
}

// The preset's control values (defaults filled in), overridden by the spec's.
Result<std::map<std::string, double>> specControlValues(const ComponentsDocument& doc, const PoseSpec& spec) {
  std::map<std::string, double> values;
  if (!spec.preset.empty()) {
    auto preset = presetControls(doc, spec.preset);
    if (!preset) return preset.error();
    values = std::move(*preset);
  }
  for (const auto& [name, value] : spec.controls) values[name] = value;
  return values;
}

// The nodes with `rotations` (Euler degrees) composed after their rest rotation.
std::vector<Node> rotatedNodes(const std::vector<Node>& nodes, const std::map<std::string, Eigen::Vector3d>& rotations) {
  const std::map<std::string, int> index = nodeIndexByName(nodes);
  std::vector<Node> out = nodes;
  for (const auto& [name, degrees] : rotations) {
    Node& node = out[static_cast<std::size_t>(index.at(name))];
    node.rotation = (node.rotation.normalized() * Eigen::Quaterniond(eulerDegreesToRotation(degrees))).normalized();
  }
  return out;
}

// Aim-constrained joints turned from their rest orientation by the aim's
// turn (model frame) under their parents as posed: local rotation
// P^T * turn * W_rest, rotations only (scales on the way taken as uniform).
// The aim sets the joint's orientation: its own rotations give way.
std::vector<Node> aimedNodes(const std::vector<Node>& rest_nodes, std::vector<Node> nodes,
                             const std::map<std::string, Eigen::Matrix3d>& aims) {
  if (aims.empty()) return nodes;
  const std::map<std::string, int> index = nodeIndexByName(nodes);
  const std::vector<Eigen::Matrix4d> rest_world = nodeWorldTransforms(rest_nodes);
  auto rotationOf = [](const Eigen::Matrix4d& m) {
    Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
    for (int k = 0; k < 3; ++k) r.col(k).normalize();
    return r;
  };
  for (const auto& [name, turn] : aims) {
    const auto n = static_cast<std::size_t>(index.at(name));
    const int parent = nodes[n].parent;
    const Eigen::Matrix3d parent_rotation =
        parent < 0 ? Eigen::Matrix3d::Identity() : rotationOf(nodeWorldTransforms(nodes)[static_cast<std::size_t>(parent)]);
    nodes[n].rotation = Eigen::Quaterniond(parent_rotation.transpose() * turn * rotationOf(rest_world[n])).normalized();
  }
  return nodes;
}

// Joints carried by clusters: the cluster's motion C (model frame, about
// the rest) put where the skeleton has the joint now,
// world = W_now * W_rest^-1 * C * W_rest, so a part skinned to the joint
// lands where the face's vertices skinned to it land after the cluster.
// Local TRS under the parent as posed (rotation and scale by polar
// decomposition).
std::vector<Node> carriedNodes(const std::vector<Node>& rest_nodes, std::vector<Node> nodes,
                               const std::map<std::string, Eigen::Matrix4d>& carried) {
  if (carried.empty()) return nodes;
  const std::map<std::string, int> index = nodeIndexByName(nodes);
  const std::vector<Eigen::Matrix4d> rest_world = nodeWorldTransforms(rest_nodes);
  for (const auto& [name, motion] : carried) {
    const auto n = static_cast<std::size_t>(index.at(name));
    const std::vector<Eigen::Matrix4d> now_world = nodeWorldTransforms(nodes);  // a carried parent has moved
    const Eigen::Matrix4d world = now_world[n] * rest_world[n].inverse() * motion * rest_world[n];
    const int parent = nodes[n].parent;
    const Eigen::Matrix4d parent_world = parent < 0 ? Eigen::Matrix4d::Identity() : now_world[static_cast<std::size_t>(parent)];
    const Eigen::Affine3d local(parent_world.inverse() * world);
    Eigen::Matrix3d rotation, scaling;
    local.computeRotationScaling(&rotation, &scaling);
    nodes[n].translation = local.translation();
    nodes[n].rotation = Eigen::Quaterniond(rotation).normalized();
    nodes[n].scale = scaling.diagonal();
  }
  return nodes;
}

}  // namespace

PoseOptions jointPositionOptions(const std::vector<Node>& rest_nodes, const std::vector<Node>& spec_nodes) {
  const std::vector<Eigen::Matrix4d> rest = nodeWorldTransforms(rest_nodes);
  const std::vector<Eigen::Matrix4d> posed = nodeWorldTransforms(spec_nodes);
  PoseOptions options;
  for (std::size_t n = 0; n < rest_nodes.size(); ++n) {
    if (rest_nodes[n].name.empty()) continue;
    options.joint_rest_positions.emplace(rest_nodes[n].name, rest[n].topRightCorner<3, 1>());
    options.joint_positions.emplace(rest_nodes[n].name, posed[n].topRightCorner<3, 1>());
  }
  return options;
}

namespace {

// Adds what the controls drive to the report's morph weights and joint
// rotations; a name the rig lacks is an error when its amount is not zero.
Status addDrivenAmounts(const Rig& rig, const ComponentsPose& pose, const PoseLabels& labels, PoseReport& report) {
  const std::vector<std::string> targets = morphTargetNames(rig);
  for (const auto& [name, weight] : pose.morph_weights) {
    if (std::find(targets.begin(), targets.end(), name) != targets.end()) {
      report.morph_weights[name] += weight;
    } else if (weight != 0.0) {
      return makeError(ErrorCode::kInvalidArgument, labels.components + ": controls drive morph target \"" + name +
                                                        "\", which the rig does not have" + didYouMean(name, targets));
    }
  }
  const std::map<std::string, int> nodes = nodeIndexByName(rig.nodes);
  for (const auto& [name, turn] : pose.joint_aims) report.joint_aims[name] = turn;  // joints checked before evaluating
  for (const auto& [name, degrees] : pose.joint_rotations) {
    if (nodes.count(name)) {
      auto [it, fresh] = report.joint_rotations.emplace(name, Eigen::Vector3d::Zero());
      it->second += degrees;
    } else if (!degrees.isZero(0.0)) {
      return makeError(ErrorCode::kInvalidArgument, labels.components + ": controls drive joint \"" + name +
                                                        "\", which the rig does not have" +
                                                        didYouMean(name, keysOf(nodes)));
    }
  }
  return Ok{};
}

// An open part (lashes: not isSolid) rides on the face's components
// motion: a piece of it that hangs on the skin (touches it, within
// kPartAttachReach of the face's size, and lies near it, median distance
// within kPartHangReach) is attached by the face vertices it touches, and
// each of its vertices moves as its nearest few of those (inverse
// distance), so a lash strip closes with its lid as one strip. Solid parts
// (eyeballs, teeth), loose pieces and pieces deep inside the head that only
// touch the skin somewhere (gums and tongue in the mouth) move only by their
// joints.
constexpr double kPartAttachReach = 0.005;  // of the face's bounding-box diagonal
constexpr double kPartHangReach = 0.02;
constexpr int kPartAnchors = 3;

// Per piece: whether it hangs on the face (above), from each vertex's nearest face vertex.
std::vector<char> piecesOnTheSkin(const MeshPieces& pieces, const std::vector<PointCloudIndex::Neighbour>& nearest,
                                  double attach, double hang) {
  std::vector<char> touches(static_cast<std::size_t>(pieces.count), 0);
  std::vector<std::vector<double>> distances(static_cast<std::size_t>(pieces.count));
  for (std::size_t v = 0; v < nearest.size(); ++v) {
    const int piece = pieces.vertex_piece[v];
    if (piece < 0 || nearest[v].index < 0) continue;
    if (nearest[v].sq_distance <= attach * attach) touches[static_cast<std::size_t>(piece)] = 1;
    distances[static_cast<std::size_t>(piece)].push_back(std::sqrt(nearest[v].sq_distance));
  }
  std::vector<char> on(static_cast<std::size_t>(pieces.count), 0);
  for (std::size_t p = 0; p < on.size(); ++p) {
    std::vector<double>& d = distances[p];
    if (!touches[p] || d.empty()) continue;
    std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
    on[p] = d[d.size() / 2] <= hang ? 1 : 0;
  }
  return on;
}

}  // namespace

PartRides preparePartRides(const Rig& rig) {
  PartRides rides;
  rides.parts.resize(rig.parts.size());
  if (rig.parts.empty()) return rides;
  const Eigen::MatrixX3d& rest_face = rig.mesh.positions;
  const PointCloudIndex face(rest_face);
  const double diagonal = boundingBoxDiagonal(rest_face);
  const double reach = kPartAttachReach * diagonal;
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    const RigPart& part = rig.parts[p];
    if (isSolid(part.mesh)) continue;
    const std::vector<PointCloudIndex::Neighbour> nearest = face.nearest(part.mesh.positions);
    const MeshPieces pieces = meshPieces(part.mesh, coincidentVertexRepresentatives(part.mesh.positions));
    const std::vector<char> attached = piecesOnTheSkin(pieces, nearest, reach, kPartHangReach * diagonal);
    std::vector<int> anchors;  // face vertices the part's attached pieces touch
    for (std::size_t v = 0; v < nearest.size(); ++v) {
      const int piece = pieces.vertex_piece[v];
      if (piece < 0 || !attached[static_cast<std::size_t>(piece)] || nearest[v].sq_distance > reach * reach) continue;
      anchors.push_back(nearest[v].index);
    }
    if (anchors.empty()) continue;
    std::sort(anchors.begin(), anchors.end());
    anchors.erase(std::unique(anchors.begin(), anchors.end()), anchors.end());
    Eigen::MatrixX3d anchor_rest(static_cast<Eigen::Index>(anchors.size()), 3);
    for (std::size_t a = 0; a < anchors.size(); ++a) anchor_rest.row(static_cast<Eigen::Index>(a)) = rest_face.row(anchors[a]);
    const PointCloudIndex anchor_index(anchor_rest);
    std::vector<Eigen::Triplet<double>> entries;
    for (std::size_t v = 0; v < nearest.size(); ++v) {
      const int piece = pieces.vertex_piece[v];
      if (piece < 0 || !attached[static_cast<std::size_t>(piece)]) continue;
      const auto row = static_cast<Eigen::Index>(v);
      const std::size_t first = entries.size();
      double total = 0.0;
      for (const auto& n : anchor_index.nearest(Eigen::Vector3d(part.mesh.positions.row(row).transpose()), kPartAnchors)) {
        const double w = 1.0 / (std::sqrt(n.sq_distance) + 1e-6 * reach);
        entries.emplace_back(static_cast<int>(v), anchors[static_cast<std::size_t>(n.index)], w);
        total += w;
      }
      for (std::size_t e = first; e < entries.size(); ++e) {
        entries[e] = Eigen::Triplet<double>(entries[e].row(), entries[e].col(), entries[e].value() / total);
      }
    }
    rides.parts[p].resize(part.mesh.positions.rows(), rest_face.rows());
    rides.parts[p].setFromTriplets(entries.begin(), entries.end());
  }
  return rides;
}

namespace {

// Per part, its vertices' ride on the face's components `displacement`
// (#V by 3 of the part, 0 rows for a part that does not ride).
std::vector<Eigen::MatrixX3d> partRides(const PartRides& rides, const Eigen::MatrixX3d& displacement) {
  std::vector<Eigen::MatrixX3d> out(rides.parts.size());
  if (displacement.isZero(0.0)) return out;
  for (std::size_t p = 0; p < rides.parts.size(); ++p) {
    if (rides.parts[p].rows() > 0) out[p] = rides.parts[p] * displacement;
  }
  return out;
}

// Components on the face: the posed face (mesh space) and each part's ride
// on it (partRides); control values and clamped controls and the driven
// amounts go to `report`.
struct ComponentsMotion {
  Eigen::MatrixX3d face;
  std::vector<Eigen::MatrixX3d> part_rides;
  // Per part, its vertices that ride (1), when clusters carry joints: they
  // follow the face's components motion, so, like the face, they are skinned
  // without the carried joints' motion (empty: none ride, or nothing carried).
  std::vector<std::vector<char>> riding;
};

std::vector<std::vector<char>> ridingVertices(const PartRides& rides) {
  std::vector<std::vector<char>> out(rides.parts.size());
  for (std::size_t p = 0; p < rides.parts.size(); ++p) {
    const auto& ride = rides.parts[p];
    if (ride.rows() == 0) continue;
    out[p].assign(static_cast<std::size_t>(ride.rows()), 0);
    for (Eigen::Index v = 0; v < ride.outerSize(); ++v) {
      out[p][static_cast<std::size_t>(v)] = Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator(ride, v) ? 1 : 0;
    }
  }
  return out;
}

Result<ComponentsMotion> applyComponents(const Rig& rig, const ComponentsDocument& doc, const PoseSpec& spec,
                                         const PoseLabels& labels, const PartRides* rides, PoseReport& report) {
  const ComponentsMeshCounts counts{rig.mesh.vertexCount(), rig.mesh.triangleCount()};
  if (auto ok = validateComponents(doc, labels.components, counts); !ok) return ok.error();
  auto controls = specControlValues(doc, spec);
  if (!controls) return makeError(controls.error().code, labels.components + ": " + controls.error().message);
  // Joints the document names (aimed, carried) must be the rig's.
  const std::map<std::string, int> nodes = nodeIndexByName(rig.nodes);
  auto missingJoint = [&](const std::string& where, const std::string& joint) {
    return makeError(ErrorCode::kInvalidArgument, labels.components + ": " + where + "the rig has no joint \"" + joint +
                                                      "\"" + didYouMean(joint, keysOf(nodes)));
  };
  for (std::size_t i = 0; i < doc.aim_constraints.size(); ++i) {
    const AimConstraint& c = doc.aim_constraints[i];
    if (c.joint && !nodes.count(c.constrained)) {
      return missingJoint("aim_constraints[" + std::to_string(i) + "] \"" + c.name + "\": ", c.constrained);
    }
  }
  for (std::size_t i = 0; i < doc.clusters.size(); ++i) {
    const Cluster& c = doc.clusters[i];
    if (!c.joint.empty() && !nodes.count(c.joint)) {
      return missingJoint("clusters[" + std::to_string(i) + "] \"" + c.name + "\": joint: ", c.joint);
    }
  }
  PoseOptions options = jointPositionOptions(rig.nodes, rotatedNodes(rig.nodes, spec.joint_rotations));
  options.validated = true;
  auto pose = evaluatePose(rig.mesh.positions, rig.mesh.triangles, doc, *controls, options);
  if (!pose) return makeError(pose.error().code, labels.components + ": " + pose.error().message);
  if (auto ok = addDrivenAmounts(rig, *pose, labels, report); !ok) return ok.error();
  for (const Cluster& c : doc.clusters) {
    if (!c.joint.empty()) report.carried_joints[c.joint] = pose->cluster_transforms.at(c.name).matrix();
  }
  report.control_values = pose->control_values;
  report.clamped_controls = pose->clamped_controls;
  ComponentsMotion motion;
  motion.part_rides.resize(rig.parts.size());
  const Eigen::MatrixX3d displacement = pose->positions - rig.mesh.positions;
  const bool moved = !displacement.isZero(0.0), carried = !report.carried_joints.empty();
  if (!rig.parts.empty() && (moved || carried)) {
    std::optional<PartRides> prepared;
    if (!rides) prepared = preparePartRides(rig);
    const PartRides& part_rides = rides ? *rides : *prepared;
    if (moved) motion.part_rides = partRides(part_rides, displacement);
    if (carried) motion.riding = ridingVertices(part_rides);
  }
  motion.face = std::move(pose->positions);
  return motion;
}

// A part posed with the joints clusters carry (`carried`), its riding
// vertices' rows taken from `with_face` (posed as the face is), so that a
// vertex on the skin (stubble skinned to a carried jaw) moves once.
Eigen::MatrixX3d rideOnce(Eigen::MatrixX3d carried, const Eigen::MatrixX3d& with_face, const std::vector<char>& riding) {
  for (std::size_t v = 0; v < riding.size(); ++v) {
    if (riding[v]) carried.row(static_cast<Eigen::Index>(v)) = with_face.row(static_cast<Eigen::Index>(v));
  }
  return carried;
}

// What poseRig and poseAtRest share: the components (when given) and the
// spec's own morph weights and joint rotations in `report`, and the
// skeleton at the pose.
struct PoseAmounts {
  std::optional<ComponentsMotion> components;
  std::vector<Node> face_nodes;  // rotations and aims: what the face is skinned with
  std::vector<Node> part_nodes;  // and the joints clusters carry: what everything else is
};

Result<PoseAmounts> poseAmounts(const Rig& rig, const ComponentsDocument* components, const PoseSpec& spec,
                                const PoseLabels& labels, const PartRides* rides, PoseReport& report) {
  if (auto ok = checkSpecNames(rig, components, spec, labels); !ok) return ok.error();
  PoseAmounts amounts;
  if (components) {
    auto motion = applyComponents(rig, *components, spec, labels, rides, report);
    if (!motion) return motion.error();
    amounts.components = std::move(*motion);
  }
  for (const auto& [name, weight] : spec.morph_weights) report.morph_weights[name] += weight;
  for (const auto& [name, degrees] : spec.joint_rotations) {
    auto [it, fresh] = report.joint_rotations.emplace(name, Eigen::Vector3d::Zero());
    it->second += degrees;
  }
  amounts.face_nodes = aimedNodes(rig.nodes, rotatedNodes(rig.nodes, report.joint_rotations), report.joint_aims);
  amounts.part_nodes = carriedNodes(rig.nodes, amounts.face_nodes, report.carried_joints);
  return amounts;
}

// Part p's riding vertices when some ride and clusters carry joints, else null.
const std::vector<char>* ridingOf(const PoseAmounts& amounts, std::size_t p) {
  if (!amounts.components || amounts.components->riding.size() <= p || amounts.components->riding[p].empty()) {
    return nullptr;
  }
  return &amounts.components->riding[p];
}

// #targets weights: the defaults, with the targets named in `named` set.
Eigen::VectorXd morphWeightsOf(const std::vector<MorphTarget>& targets, const Eigen::VectorXd& defaults,
                               const std::map<std::string, double>& named) {
  const auto count = static_cast<Eigen::Index>(targets.size());
  Eigen::VectorXd weights = defaults.size() == count ? defaults : Eigen::VectorXd::Zero(count);
  for (Eigen::Index k = 0; k < count; ++k) {
    const auto found = named.find(targets[static_cast<std::size_t>(k)].name);
    if (found != named.end()) weights(k) = found->second;
  }
  return weights;
}

// An unskinned mesh at `node` moved with its node's change from rest (in
// glTF it moves with its node; poseMesh leaves it where it is).
Eigen::MatrixX3d movedWithNode(Eigen::MatrixX3d positions, int node, const std::vector<Eigen::Matrix4d>& rest_world,
                               const std::vector<Eigen::Matrix4d>& posed_world) {
  if (node < 0 || static_cast<std::size_t>(node) >= posed_world.size() ||
      posed_world[static_cast<std::size_t>(node)] == rest_world[static_cast<std::size_t>(node)]) {
    return positions;
  }
  const Eigen::Matrix4d motion = posed_world[static_cast<std::size_t>(node)] * rest_world[static_cast<std::size_t>(node)].inverse();
  return (positions * motion.topLeftCorner<3, 3>().transpose()).rowwise() + motion.topRightCorner<3, 1>().transpose();
}

// #V by 3 world positions of one mesh (the face or partAsRig of a part) at
// the pose.
Eigen::MatrixX3d posedMeshPositions(const Rig& mesh_rig, const std::vector<Node>& posed_nodes,
                                    const std::map<std::string, double>& morph_weights,
                                    const std::vector<Eigen::Matrix4d>& rest_world,
                                    const std::vector<Eigen::Matrix4d>& posed_world) {
  Pose pose;
  pose.nodes = posed_nodes;
  pose.morph_weights = morphWeightsOf(mesh_rig.morph_targets, mesh_rig.morph_default_weights, morph_weights);
  Eigen::MatrixX3d positions = poseMesh(mesh_rig, pose);
  return mesh_rig.skin ? positions : movedWithNode(std::move(positions), mesh_rig.mesh_node, rest_world, posed_world);
}

// One mesh of the rig held at the rest skeleton (poseAtRest): `positions`
// (its rest plus the components' motion) with the named morph weights'
// deltas added and the skeleton's motion held.
struct MeshOfRig {
  const std::optional<Skin>& skin;
  const SkinWeights& weights;
  const std::vector<MorphTarget>& targets;
  int node;
};

Eigen::MatrixX3d heldAtRest(const MeshOfRig& mesh, Eigen::MatrixX3d positions, const PoseReport& report,
                            const std::vector<std::string>& baked_presets, const std::vector<Node>& rest_nodes,
                            const std::vector<Node>& posed_nodes) {
  for (const MorphTarget& target : mesh.targets) {
    const auto weight = report.morph_weights.find(target.name);
    if (weight == report.morph_weights.end() || weight->second == 0.0) continue;
    if (std::find(baked_presets.begin(), baked_presets.end(), target.name) != baked_presets.end()) continue;
    positions += weight->second * target.position_deltas;
  }
  if (mesh.skin && mesh.weights.size() > 0) {  // as partAsRig: a part without weights is not skinned
    return holdSkeletonPose(*mesh.skin, mesh.weights, rest_nodes, posed_nodes, std::move(positions));
  }
  return movedWithNode(std::move(positions), mesh.node, nodeWorldTransforms(rest_nodes), nodeWorldTransforms(posed_nodes));
}

Mesh staticMesh(Mesh mesh, Eigen::MatrixX3d positions) {
  mesh.positions = std::move(positions);
  mesh.normals = computeVertexNormals(mesh.positions, mesh.triangles);
  return mesh;
}

int countMoved(const Eigen::MatrixX3d& rest, const Eigen::MatrixX3d& posed) {
  // Skinning at rest reproduces the rest only to rounding: a file's float32
  // nodes and inverse binds to about 1e-7 of the model's size.
  const double tolerance = 1e-6 * boundingBoxDiagonal(rest);
  return static_cast<int>(((posed - rest).rowwise().norm().array() > tolerance).count());
}

}  // namespace

Result<PosedRig> poseRig(Rig rig, const ComponentsDocument* components, const PoseSpec& spec, const PoseLabels& labels) {
  PosedRig out;
  PoseReport& report = out.report;
  auto amounts = poseAmounts(rig, components, spec, labels, nullptr, report);
  if (!amounts) return amounts.error();
  const Eigen::MatrixX3d rest_face = rig.mesh.positions;
  if (amounts->components) {
    rig.mesh.positions = std::move(amounts->components->face);
    for (std::size_t p = 0; p < rig.parts.size(); ++p) {
      const Eigen::MatrixX3d& ride = amounts->components->part_rides[p];
      if (ride.rows() > 0) rig.parts[p].mesh.positions += ride;
    }
  }
  const std::vector<Node>& face_nodes = amounts->face_nodes;
  const std::vector<Node>& posed_nodes = amounts->part_nodes;
  const std::vector<Eigen::Matrix4d> rest_world = nodeWorldTransforms(rig.nodes);
  const std::vector<Eigen::Matrix4d> posed_world = nodeWorldTransforms(posed_nodes);
  const std::vector<Eigen::Matrix4d> face_world = nodeWorldTransforms(face_nodes);
  Rig& posed = out.rig;
  posed.mesh = staticMesh(rig.mesh, posedMeshPositions(rig, face_nodes, report.morph_weights, rest_world, face_world));
  posed.mesh_name = rig.mesh_name;
  posed.nodes = posed_nodes;
  posed.mesh_node = rig.mesh_node;
  posed.attributes = std::move(rig.attributes);
  posed.materials = std::move(rig.materials);
  posed.images = std::move(rig.images);
  posed.triangle_materials = std::move(rig.triangle_materials);
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    const RigPart& part = rig.parts[p];
    const Rig part_rig = partAsRig(rig, part);
    Eigen::MatrixX3d positions = posedMeshPositions(part_rig, posed_nodes, report.morph_weights, rest_world, posed_world);
    if (const std::vector<char>* riding = ridingOf(*amounts, p)) {
      positions = rideOnce(std::move(positions),
                           posedMeshPositions(part_rig, face_nodes, report.morph_weights, rest_world, face_world), *riding);
    }
    RigPart static_part;
    static_part.name = part.name;
    static_part.node = part.node;
    static_part.mesh = staticMesh(part.mesh, std::move(positions));
    static_part.attributes = part.attributes;
    static_part.triangle_materials = part.triangle_materials;
    posed.parts.push_back(std::move(static_part));
  }
  report.moved_face_vertices = countMoved(rest_face, posed.mesh.positions);
  return out;
}

Result<RestSpacePose> poseAtRest(const Rig& rig, const ComponentsDocument* components, const PoseSpec& spec,
                                 const PoseLabels& labels, const PartRides* rides) {
  RestSpacePose out;
  auto amounts = poseAmounts(rig, components, spec, labels, rides, out.report);
  if (!amounts) return amounts.error();
  const MeshOfRig face{rig.skin, rig.weights, rig.morph_targets, rig.mesh_node};
  out.face = heldAtRest(face, amounts->components ? amounts->components->face : rig.mesh.positions, out.report,
                        rig.baked_presets, rig.nodes, amounts->face_nodes);
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    const RigPart& part = rig.parts[p];
    Eigen::MatrixX3d positions = part.mesh.positions;
    if (amounts->components && amounts->components->part_rides[p].rows() > 0) positions += amounts->components->part_rides[p];
    const MeshOfRig mesh{rig.skin, part.weights, part.morph_targets, part.node};
    const std::vector<char>* riding = ridingOf(*amounts, p);
    Eigen::MatrixX3d held = heldAtRest(mesh, positions, out.report, rig.baked_presets, rig.nodes, amounts->part_nodes);
    if (riding) {
      held = rideOnce(std::move(held),
                      heldAtRest(mesh, std::move(positions), out.report, rig.baked_presets, rig.nodes, amounts->face_nodes),
                      *riding);
    }
    out.parts.push_back(std::move(held));
  }
  return out;
}

}  // namespace core
