// bakePresets: see bake.h.

#include "core/components/bake.h"

#include <algorithm>

#include "core/components/pose.h"
#include "core/components/pose_spec.h"

namespace core {

namespace {

bool isBakedPreset(const Rig& rig, const std::string& name) {
  return std::find(rig.baked_presets.begin(), rig.baked_presets.end(), name) != rig.baked_presets.end();
}

// The preset's deltas on the rig's face: the components' motion plus the
// rig's own shapes it drives.
Result<MorphTarget> bakePreset(const Rig& rig, const ComponentsDocument& doc, const std::string& name,
                               BakeReport& report) {
  auto controls = presetControls(doc, name);
  if (!controls) return controls.error();
  auto pose = evaluatePose(rig.mesh.positions, rig.mesh.triangles, doc, *controls, jointPositionOptions(rig.nodes, rig.nodes));
  if (!pose) return makeError(pose.error().code, "preset '" + name + "': " + pose.error().message);
  MorphTarget target;
  target.name = name;
  target.position_deltas = pose->positions - rig.mesh.positions;
  for (const auto& [shape, weight] : pose->morph_weights) {
    if (weight == 0.0) continue;
    const int t = indexByName(rig.morph_targets, shape);
    if (t < 0) {
      return makeError(ErrorCode::kInvalidArgument, "preset '" + name + "' drives morph target '" + shape +
                                                        "', which the rig does not have" +
                                                        didYouMean(shape, namesOf(rig.morph_targets), '\''));
    }
    if (isBakedPreset(rig, shape)) continue;  // a baked preset is not a shape of the rig's own
    target.position_deltas += weight * rig.morph_targets[static_cast<std::size_t>(t)].position_deltas;
  }
  for (const auto& [joint, rotation] : pose->joint_rotations) {
    if (!rotation.isZero(0.0)) {
      report.warnings.push_back("preset '" + name + "' turns joint '" + joint +
                                "', which a morph target cannot hold: the rotation is not baked");
    }
  }
  for (const auto& [joint, turn] : pose->joint_aims) {
    if (!turn.isIdentity(1e-12)) {
      report.warnings.push_back("preset '" + name + "' aims joint '" + joint +
                                "', which a morph target cannot hold: the aim is not baked");
    }
  }
  for (const std::string& control : pose->clamped_controls) {
    report.warnings.push_back("preset '" + name + "': control '" + control + "' clamped to its range");
  }
  return target;
}

// A weight channel of the face gets a zero column for each appended target.
void widenFaceWeightChannels(Rig& rig, Eigen::Index added) {
  for (Animation& animation : rig.animations) {
    for (AnimationChannel& channel : animation.channels) {
      if (channel.path != AnimationPath::kWeights || channel.node != rig.mesh_node) continue;
      Eigen::MatrixXd widened = Eigen::MatrixXd::Zero(channel.values.rows(), channel.values.cols() + added);
      widened.leftCols(channel.values.cols()) = channel.values;
      channel.values = std::move(widened);
    }
  }
}

}  // namespace

Result<BakeReport> bakePresets(Rig& rig, const ComponentsDocument& doc, const std::vector<std::string>& presets) {
  std::vector<std::string> names = presets;
  if (names.empty()) {
    for (const auto& [name, preset] : doc.presets) names.push_back(name);
  }
  BakeReport report;
  std::vector<MorphTarget> baked;
  for (const std::string& name : names) {
    if (indexByName(rig.morph_targets, name) >= 0 && !isBakedPreset(rig, name)) {
      return makeError(ErrorCode::kInvalidArgument, "preset '" + name +
                                                        "' has the name of a morph target of the rig that is not a "
                                                        "baked preset; rename the preset or the target");
    }
    auto target = bakePreset(rig, doc, name, report);
    if (!target) return target.error();
    baked.push_back(std::move(*target));
  }
  // Everything evaluated: only now is the rig changed.
  Eigen::Index added = 0;
  for (MorphTarget& target : baked) {
    report.baked.push_back(target.name);
    const int t = indexByName(rig.morph_targets, target.name);
    if (t >= 0) {
      rig.morph_targets[static_cast<std::size_t>(t)] = std::move(target);
      continue;
    }
    rig.morph_targets.push_back(std::move(target));
    rig.baked_presets.push_back(rig.morph_targets.back().name);
    ++added;
  }
  if (added > 0) {
    const Eigen::Index before = rig.morph_default_weights.size();
    rig.morph_default_weights.conservativeResize(before + added);
    rig.morph_default_weights.tail(added).setZero();
    widenFaceWeightChannels(rig, added);
  }
  return report;
}

}  // namespace core
