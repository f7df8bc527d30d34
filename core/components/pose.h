// evaluatePose: a components document posed by control values, in the
// documented order (docs/COMPONENTS.md):
//   controls -> muscles and constraints -> clusters -> wire CVs -> deformers (wires, lattices) -> skull push.
// Blend shapes and skinning come after, elsewhere (core/rig).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "core/base/error.h"
#include "core/components/components.h"

namespace core {

struct PoseOptions {
  // Joint positions at this pose, model units: needed by constraints that target joints.
  std::map<std::string, Eigen::Vector3d> joint_positions;
  // Joint positions at rest: needed by joint targets of constraints that keep their
  // offset (maintain_offset) and of aim constraints on clusters.
  std::map<std::string, Eigen::Vector3d> joint_rest_positions;
  // The caller has already run validateComponents on this document against
  // this mesh (poseRig names its own files in the messages): not run again.
  bool validated = false;
};

struct ComponentsPose {
  Eigen::MatrixX3d positions;                       // #V by 3 posed vertex positions, model units
  std::map<std::string, double> control_values;     // every control: given or default, clamped to its range
  std::vector<std::string> clamped_controls;        // given values outside their control's range
  std::map<std::string, double> muscle_contractions;
  std::map<std::string, Eigen::Vector3d> locator_positions;
  std::map<std::string, Eigen::Matrix3d> locator_rotations;    // aim-constrained locators (object -> model frame)
  std::map<std::string, Eigen::Affine3d> cluster_transforms;   // each cluster's transform of model space
  std::map<std::string, std::vector<Eigen::Vector3d>> curve_points;    // control points, drivers applied
  std::map<std::string, std::vector<Eigen::Vector3d>> lattice_points;  // deformed control points, drivers applied
  std::map<std::string, double> morph_weights;                 // summed control drives, for the blend shapes
  std::map<std::string, Eigen::Vector3d> joint_rotations;      // Euler degrees (x, y, z), for the skeleton
  // Aim-constrained joints: the turn from their rest aim, model frame (the
  // skeleton applies it to the joint's rest orientation: poseRig).
  std::map<std::string, Eigen::Matrix3d> joint_aims;
};

// rest_positions: #V by 3 (model units), triangles: #F by 3, of a mesh with
// the document's topology. control_values: by control name; missing controls
// take their default. Errors: an invalid document (validateComponents against
// the mesh's counts), unknown control names, non-finite values, a joint
// target without a position, a muscle of zero length at rest.
Result<ComponentsPose> evaluatePose(const Eigen::MatrixX3d& rest_positions, const Eigen::MatrixX3i& triangles,
                                    const ComponentsDocument& doc, const std::map<std::string, double>& control_values,
                                    const PoseOptions& options = {});

}  // namespace core
