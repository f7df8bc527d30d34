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

// A preset baked: the face's target and, per part, its target when the
// preset moves it (0 rows when it does not).
struct BakedPreset {
  MorphTarget face;
  std::vector<Eigen::MatrixX3d> parts;
};

// The preset's pose held at the rest skeleton (poseAtRest) minus the rest.
Result<BakedPreset> bakePreset(const Rig& rig, const ComponentsDocument& doc, const std::string& name,
                               const PartRides& rides, BakeReport& report) {
  if (auto controls = presetControls(doc, name); !controls) return controls.error();
  PoseSpec spec;
  spec.preset = name;
  PoseLabels labels;
  labels.components = "preset '" + name + "'";
  auto pose = poseAtRest(rig, &doc, spec, labels, &rides);
  if (!pose) return pose.error();
  BakedPreset baked;
  baked.face.name = name;
  baked.face.position_deltas = pose->face - rig.mesh.positions;
  for (std::size_t p = 0; p < rig.parts.size(); ++p) {
    Eigen::MatrixX3d deltas = pose->parts[p] - rig.parts[p].mesh.positions;
    const bool had = indexByName(rig.parts[p].morph_targets, name) >= 0;  // baked before: replaced, even by nothing
    baked.parts.push_back(had || !deltas.isZero(0.0) ? std::move(deltas) : Eigen::MatrixX3d());
  }
  for (const std::string& control : pose->report.clamped_controls) {
    report.warnings.push_back("preset '" + name + "': control '" + control + "' clamped to its range");
  }
  return baked;
}

// A weight channel of the mesh at `node` gets a zero column for an appended target.
void widenWeightChannels(Rig& rig, int node) {
  for (Animation& animation : rig.animations) {
    for (AnimationChannel& channel : animation.channels) {
      if (channel.path != AnimationPath::kWeights || channel.node != node) continue;
      Eigen::MatrixXd widened = Eigen::MatrixXd::Zero(channel.values.rows(), channel.values.cols() + 1);
      widened.leftCols(channel.values.cols()) = channel.values;
      channel.values = std::move(widened);
    }
  }
}

// Adds `target` to a mesh's targets, or replaces the one of its name;
// returns whether it was added.
bool putTarget(std::vector<MorphTarget>& targets, Eigen::VectorXd& default_weights, MorphTarget target) {
  const int t = indexByName(targets, target.name);
  if (t >= 0) {
    targets[static_cast<std::size_t>(t)] = std::move(target);
    return false;
  }
  targets.push_back(std::move(target));
  const Eigen::Index before = default_weights.size();
  default_weights.conservativeResize(before + 1);
  default_weights(before) = 0.0;
  return true;
}

// A preset named like a morph target of the rig (face or part) that is not a baked preset.
Status checkPresetName(const Rig& rig, const std::string& name) {
  if (isBakedPreset(rig, name)) return Ok{};
  bool clash = indexByName(rig.morph_targets, name) >= 0;
  for (const RigPart& part : rig.parts) clash = clash || indexByName(part.morph_targets, name) >= 0;
  if (!clash) return Ok{};
  return makeError(ErrorCode::kInvalidArgument, "preset '" + name +
                                                    "' has the name of a morph target of the rig that is not a "
                                                    "baked preset; rename the preset or the target");
}

}  // namespace

Result<BakeReport> bakePresets(Rig& rig, const ComponentsDocument& doc, const std::vector<std::string>& presets) {
  std::vector<std::string> names = presets;
  if (names.empty()) {
    for (const auto& [name, preset] : doc.presets) names.push_back(name);
  }
  BakeReport report;
  std::vector<BakedPreset> baked;
  const PartRides rides = preparePartRides(rig);
  for (const std::string& name : names) {
    if (auto ok = checkPresetName(rig, name); !ok) return ok.error();
    auto preset = bakePreset(rig, doc, name, rides, report);
    if (!preset) return preset.error();
    baked.push_back(std::move(*preset));
  }
  // Everything evaluated: only now is the rig changed.
  for (BakedPreset& preset : baked) {
    const std::string name = preset.face.name;
    report.baked.push_back(name);
    if (putTarget(rig.morph_targets, rig.morph_default_weights, std::move(preset.face))) {
      rig.baked_presets.push_back(name);
      widenWeightChannels(rig, rig.mesh_node);
    }
    for (std::size_t p = 0; p < rig.parts.size(); ++p) {
      if (preset.parts[p].rows() == 0) continue;
      RigPart& part = rig.parts[p];
      MorphTarget target;
      target.name = name;
      target.position_deltas = std::move(preset.parts[p]);
      if (putTarget(part.morph_targets, part.morph_default_weights, std::move(target))) {
        widenWeightChannels(rig, part.node);
      }
    }
  }
  return report;
}

}  // namespace core
