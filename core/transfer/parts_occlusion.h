// Whether the rig's inner parts stay behind the face's skin: an eyeball
// behind the lids, teeth behind the lips. A part vertex pokes through when,
// looking along the face's forward axis, the front-most surface on its line
// is skin and lies behind the vertex by more than a tolerance. The face's
// openings (its boundary loops: eyes, mouth, a neck cut) are closed by caps
// for this test: a line whose front-most crossing is a cap passes through an
// opening, and what is seen through an opening (an iris, teeth in an open
// mouth) is not a poke even where it bulges past the opening's rim, as a
// cornea does by ~7 mm on the ICT rig. Skin behind the part (an eye socket,
// a mouth bag, the back of the head) never decides: only the front-most
// crossing counts, and a cap lies in front of what is behind its opening.
// docs/TRANSFER.md, "The rig's other meshes".
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/geometry/mesh.h"
#include "core/rig/rig.h"
#include "core/transfer/parts.h"

namespace core {

struct OcclusionOptions {
  // A vertex counts as in front when it stands more than this in front of
  // the skin on its line: fraction of the face's bounding-box diagonal at
  // rest (ICT: 0.001 * ~48 cm = 0.5 mm).
  double tolerance = 0.001;
};

// The direction the face looks along (unit): the normal of the
// least-squares plane through its landmarks (#L by 3, model units; on a
// face they spread over its front), on the side of `toward` (the sum of the
// skin normals at them; a target: the source's forward turned onto it).
// Zero when the landmarks span no plane (fewer than 3, or collinear).
Eigen::Vector3d faceForward(const Eigen::MatrixX3d& landmark_positions, const Eigen::Vector3d& toward);

// The face's openings and forward axis found once (fit once), then any pose
// of the face asked about any points (apply many).
class SkinOcclusion {
 public:
  // face: positions (#V by 3, rest) and triangles; its openings are the
  // boundary loops with split points (UV seams) welded. forward: unit.
  SkinOcclusion(const Mesh& face, const Eigen::Vector3d& forward, const OcclusionOptions& options = {});

  // Per point (#P by 3): how far it stands in front of the skin on its line
  // along forward, model units: positive in front, negative behind; 0 when
  // the line meets no skin or its front-most crossing is an opening's cap.
  // face_positions: #V by 3, the face at rest or posed (the same vertices).
  // Ask about every point of one pose in one call: the lines share one
  // index, a 2D grid over the face's triangles projected along forward.
  Eigen::VectorXd standOut(const Eigen::MatrixX3d& face_positions, const Eigen::MatrixX3d& points) const;

  // Points of `points` standing out more than the tolerance.
  int countInFront(const Eigen::VectorXd& stand_out) const;

  const Eigen::Vector3d& forward() const { return forward_; }
  double tolerance() const { return tolerance_; }  // model units
  int openings() const { return static_cast<int>(loops_.size()); }

 private:
  Eigen::Matrix3d axes_;     // columns: across, up (the view plane), forward
  Eigen::Vector3d forward_;
  Eigen::MatrixX3i triangles_;
  std::vector<std::vector<int>> loops_;  // capped openings, welded vertex indices in order
  double tolerance_ = 0.0;
};

// Per part: its vertices standing out more than the tolerance in front of
// `face_positions` (the face of `skin`, at rest or posed); `parts`
// positions in the face's space (bind space for a skinned rig). One grid for
// all of them.
std::vector<int> partsInFront(const SkinOcclusion& skin, const Eigen::MatrixX3d& face_positions,
                              const std::vector<const Eigen::MatrixX3d*>& parts);

// The rig's side of the check, source-only and so prepared once per rig
// (PreparedRig::parts_occlusion): its face's forward (from its landmarks,
// on the side its skin normals there face) and each part's vertices in
// front of its own skin at rest.
struct SourcePartsOcclusion {
  Eigen::Vector3d forward = Eigen::Vector3d::Zero();  // zero: no check (landmarks span no plane)
  std::vector<int> in_front;                          // per part
};

// `landmark_vertices`: the vertex of each landmark (its normal gives the side).
SourcePartsOcclusion prepareSourcePartsOcclusion(const Mesh& face, const Eigen::MatrixX3d& landmark_positions,
                                                 const std::vector<int>& landmark_vertices,
                                                 const std::vector<RigPart>& parts,
                                                 const OcclusionOptions& options = {});

// A transfer's check of its parts, at rest: fills each report's
// vertices_in_front (carried part on the target face, rest positions and
// triangles; its forward from its landmarks on the side the rig's turns to
// by `rotation`) and source_vertices_in_front. Returns, per part the rig
// keeps behind its skin (at most 1% of its vertices in front: eyeballs,
// teeth, a tongue, not lashes) that stands in front of the target's skin at
// more vertices than of the rig's, a warning naming it and the counts.
std::vector<std::string> checkPartsBehindSkin(const SourcePartsOcclusion& source, const std::vector<RigPart>& source_parts,
                                              const Mesh& target_face, const Eigen::MatrixX3d& target_landmark_positions,
                                              const Eigen::Matrix3d& rotation, CarriedParts& carried,
                                              const OcclusionOptions& options = {});

}  // namespace core
