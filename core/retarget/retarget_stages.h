// (internal to core/retarget) The stages of retargetMocap (retarget.cpp),
// each a function of plain data in and out, in the order it runs them:
//
//   retarget.cpp
//     checkRetargetInputs    mesh, distances, clip and options agree
//     findMarkersInClip      the placed markers by name in the clip (absent ones: retargetMarkersInClip)
//   calibration.cpp
//     calibrateClip          rest frame -> placed markers; head motion; displacements in mesh space
//   retarget.cpp
//     markerRbfOptions       the RBF of the job (gamma, polynomial, stiffness)
//     factoriseMarkers       the marker system factorised once; its basis on the vertices
//     (solve)                RbfFactorization::solve of all frames at once
//     markerResiduals        the RBF at the markers against what it interpolates
//     meshRig                the mesh and its node
//   bake.cpp
//     bakeFrames, bakeModes  morph targets and their per-frame weights (exact, or the leading modes)
//   retarget.cpp
//     addMocapAnimation      the morph targets and their animation joined to the rig
//     assembleReport         the report from the inputs and the stages' products
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/base/error.h"
#include "core/geometry/similarity.h"
#include "core/retarget/retarget.h"

namespace core {

// Calibration: per-marker linear maps of mocap displacements into mesh space.
struct Calibration {
  std::vector<Eigen::Matrix3d> maps;  // #M: J_i * s * R
  Similarity similarity;
  double similarity_rms = 0.0;
  double min_singular = 0.0, max_singular = 0.0;
};

// Each frame's marker displacements from the rest frame, mapped into mesh
// space by the calibration (head motion removed first when asked), and how
// far the head and the markers moved.
struct MeshSpaceDisplacements {
  Eigen::MatrixXd rhs;                  // #M by 3F (column 3f + c), model units: what the RBF interpolates
  double head_max_rotation_deg = 0.0;
  double head_max_translation = 0.0;    // model units
  double max_marker_displacement = 0.0; // model units
};

// The clip calibrated: rest frame -> placed markers (a similarity and, with
// RetargetOptions::calibration_jacobian, a TPS's Jacobian per marker); each
// frame's displacements in mesh space, rigid head motion measured on the head
// markers and removed when RetargetOptions::remove_head_motion.
struct CalibratedClip {
  Calibration calibration;
  std::vector<Eigen::Index> head;  // the head markers, indices into the marker set
  MeshSpaceDisplacements displacements;
};

// column: #M, each placed marker's index in the clip (all present).
Result<CalibratedClip> calibrateClip(const MarkerDistances& distances, const MarkerTrajectories& clip,
                                     const std::vector<int>& column, const RetargetOptions& options);

// The bake: morph targets and their weights per frame.
struct BakedMotion {
  std::vector<MorphTarget> targets;
  Eigen::MatrixXd frame_weights;  // #frames by #targets: the weights channel's values
  RetargetReport report;          // only the bake's fields set: exact, rank, tolerance_met, errors, singular values
  double evaluate_ms = 0.0;       // vertex deltas (and the measured max error)
  double bake_ms = 0.0;           // SVD, rank, morph targets
};

// Exact: one morph target per frame, one-hot weights. weights: #K by 3F
// solved RBF weights (column 3f + c); basis: #V by #K.
BakedMotion bakeFrames(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& weights);

// Compressed: the leading modes of the displacement field, as many as
// `bake` asks (BakeOptions).
BakedMotion bakeModes(const Eigen::MatrixXd& basis, const Eigen::MatrixXd& weights, const BakeOptions& bake);

}  // namespace core
