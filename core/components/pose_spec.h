// One pose of a rig, as a person names it (the "pose JSON"), and the rig
// posed by it as a static rig:
//   {"preset": "smile",                      a preset of the components document
//    "controls": {"smile": 0.5},             component controls (override the preset's values)
//    "morph_weights": {"jawOpen": 1},        morph targets by name
//    "joints": {"jaw": [10, 0, 0]}}          Euler degrees X, then Y, then Z, after the rest rotation
// every key optional, unknown keys errors. parsePoseSpec checks the shape and
// values; poseRig checks the names against a rig and its components document
// ("did you mean") and evaluates in this order:
//   controls -> evaluatePose on the face's rest positions (core/components/pose.h)
//   -> the posed face replaces its rest -> morph weights and joint rotations
//   (given + driven by the controls; an aim-constrained joint takes its aim)
//   through poseMesh (core/rig/skinning.h), on the face and on every part;
//   a joint carried by a cluster (Cluster::joint) moves with it for the
//   parts only: the cluster has already moved the face.
//   Components move a solid part (eyeball, teeth) only through the joints
//   they turn; an open part touching the face (lashes) rides on the face's
//   components motion as well.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "core/base/error.h"
#include "core/components/components.h"
#include "core/components/pose.h"
#include "core/rig/rig.h"

namespace core {

struct PoseSpec {
  std::string preset;                                      // preset name; empty: none
  std::map<std::string, double> controls;                  // control name -> value, over the preset's
  std::map<std::string, double> morph_weights;             // morph target name -> weight, plus the controls' drives
  std::map<std::string, Eigen::Vector3d> joint_rotations;  // node name -> Euler degrees (x, y, z), plus the controls'
};

// `label` (the file name) starts every message, followed by the field:
// `pose.json: morph_weights.jawOpen: must be a finite number`.
Result<PoseSpec> parsePoseSpec(std::string_view json_text, const std::string& label);
Result<PoseSpec> readPoseSpec(const std::filesystem::path& path);

// Names of the inputs in messages (file names for a CLI run).
struct PoseLabels {
  std::string pose = "pose";
  std::string components = "components";
};

struct PoseReport {
  std::map<std::string, double> control_values;             // every control of the document, as evaluated
  std::vector<std::string> clamped_controls;                // given outside their control's range
  std::map<std::string, double> morph_weights;              // named by the pose or its controls: the summed weight
  std::map<std::string, Eigen::Vector3d> joint_rotations;   // the same for joints, Euler degrees
  std::map<std::string, Eigen::Matrix3d> joint_aims;         // aim-constrained joints: turn from rest, model frame
  std::map<std::string, Eigen::Matrix4d> carried_joints;     // joints carried by clusters: the cluster's transform, model frame
  int moved_face_vertices = 0;                              // face vertices off their rest position
};

// Joint (named node) positions for constraints that target or aim joints:
// at rest (rest_nodes) and at a pose (posed_nodes).
PoseOptions jointPositionOptions(const std::vector<Node>& rest_nodes, const std::vector<Node>& posed_nodes);

struct PosedRig {
  // The face and every part at the pose, static: no skin, weights, morph
  // targets or animations; the nodes at the pose; normals recomputed.
  Rig rig;
  PoseReport report;
};

// `rig` is taken by value because its face's rest positions are replaced by
// the components' posed ones (move it in when done with it). `components`:
// nullptr when the rig has none (then the spec may hold no preset or
// controls). Morph weights name the face's or a part's targets; each mesh's
// targets of that name take the weight (the others keep their defaults).
// An unskinned mesh follows its node, as in glTF. A part's vertices that
// ride on the face's components (PartRides) move with the face, not again
// with a joint a cluster carries (as the face). Errors: unknown names
// ("did you mean"), a document that does not fit the face, what evaluatePose
// refuses.
Result<PosedRig> poseRig(Rig rig, const ComponentsDocument* components, const PoseSpec& spec,
                         const PoseLabels& labels = {});

// The pose held by the rig's meshes alone at the rig's rest skeleton, each
// in its own (bind) space: what a morph target of the pose holds
// (bakePresets). Per mesh: rest + the components' motion (the face, a part's
// ride on it) + the named morph weights times their deltas (a baked
// preset's own target left out) + the skeleton's motion held by
// holdSkeletonPose (the face and the parts' riding vertices at the rotations
// and aims; the rest of the parts at the joints clusters carry as well); an
// unskinned mesh takes its node's motion.
// Errors: as poseRig's.
// How the rig's open parts ride on its face's components motion (poseRig):
// per part a #V(part) by #V(face) matrix, rows summing to 1 (0 rows: the
// part does not ride). Depends only on the rig's rest meshes: prepared once
// for many poses (bakePresets).
struct PartRides {
  std::vector<Eigen::SparseMatrix<double, Eigen::RowMajor>> parts;  // per Rig::parts
};
PartRides preparePartRides(const Rig& rig);

struct RestSpacePose {
  Eigen::MatrixX3d face;                // #V by 3
  std::vector<Eigen::MatrixX3d> parts;  // per Rig::parts
  PoseReport report;
};
// `rides`: preparePartRides(rig), or nullptr to prepare them here.
Result<RestSpacePose> poseAtRest(const Rig& rig, const ComponentsDocument* components, const PoseSpec& spec,
                                 const PoseLabels& labels = {}, const PartRides* rides = nullptr);

}  // namespace core
