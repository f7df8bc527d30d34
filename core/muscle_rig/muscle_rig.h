// The reference muscle rig of Orvalho-style "Murphy" rigs (paper 001,
// sections 4.1-4.3, Table 4.1; chapter 6 Tables 6.1-6.2), built on any face
// that carries the 68 iBUG landmarks, as a components document
// (core/components): 26 muscle parameters (12 muscles per side, procerus and
// mentalis), each moving a locator at its insertion; the locators drive the
// control points of the 16 linear wires of Table 4.1 (brows, forehead, nose,
// cheeks, nasolabial folds, four mouth-corner and two mouth-centre lip wires),
// whose deformation sets keep the lower lip out of the upper-lip wires and
// vice versa; crease clusters triggered by the frontalis and corrugators; a
// skull sphere the forehead is pushed out of; jaw and eyelid clusters (the
// paper's jaw and eyelid joints, as clusters so that any mesh, skinned or
// not, takes the rig without a new skeleton); the eye rig (gaze aim, lids
// following it, lower lids, eyelid sculptors); descriptive controls (Table
// 6.2) and 15 expression presets (the six universal ones first).
//
// Every distance is a fraction of the face's inter-ocular distance (face_frame.h).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "core/base/error.h"
#include "core/components/components.h"
#include "core/geometry/mesh.h"
#include "core/io/landmarks.h"

namespace core {

struct MuscleRigOptions {
  double wire_dropoff = 1.0;       // scales every wire's dropoff distance d0 (each a fraction of the iod)
  double muscle_depth = 0.12;      // muscle origins sit this far (iod) behind the skin: the skull attachment
  double expression_gain = 1.0;    // scales how far each muscle moves the skin at full contraction
  double jaw_open_degrees = 22.0;  // jaw rotation at jaw_open = 1
  // The rig's named joints, world transforms at rest (namedNodeTransforms):
  // a joint at an eye's centre (within 0.15 iod of where the eye rig puts
  // it) is aimed with the eye; one at the jaw's hinge (within 0.25 iod) is
  // the jaw cluster's pivot and is carried by it (what is skinned to it,
  // lower teeth and gums, opens with the jaw).
  std::map<std::string, Eigen::Matrix4d> joints;
  // The face's skin weights per joint (faceJointWeights): the jaw joint's,
  // when it has them, are the jaw cluster's weights (the studio's own
  // skinning of the jaw, smoother than the rig's drawn band).
  std::map<std::string, Eigen::VectorXd> joint_weights;
  std::string label = "face";      // starts every message (usually the mesh file name)
};

struct MuscleRig {
  ComponentsDocument components;         // validated against the face
  std::vector<std::string> muscle_names;  // the 26 muscle parameters
};

// face: the mesh the rig is laid on (its rest positions and triangles);
// landmarks: the 68 iBUG names (muscleRigLandmarkNames()). Errors: a missing
// landmark (named), landmarks off the mesh, a degenerate frame.
Result<MuscleRig> buildMuscleRig(const Mesh& face, const LandmarkSet& landmarks, const MuscleRigOptions& options = {});

}  // namespace core
