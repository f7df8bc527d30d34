// The stages of buildMuscleRig (muscle_rig.cpp), one concern per file:
// muscles and wires (muscle_rig.cpp), jaw, eyelids, creases and skull
// (muscle_rig_regions.cpp), controls and presets (muscle_rig_expressions.cpp).
// Internal to core/muscle_rig.
#pragma once

#include <string>
#include <vector>

#include "core/components/components.h"
#include "core/geometry/mesh.h"
#include "core/muscle_rig/face_frame.h"
#include "core/muscle_rig/muscle_rig.h"

namespace core::muscle_rig_detail {

// +1: the subject's left (+right axis), -1: the subject's right.
inline const char* sideSuffix(int side) { return side > 0 ? "_L" : "_R"; }

// The lip and lid sets of the face (frame coordinates of every vertex).
struct FaceRegions {
  Eigen::MatrixX3d local;  // #V by 3: each vertex in frame coordinates (units of iod)
  MouthLine mouth;
  double lids_top = 0.0;     // frame y above which the brow wires may act
  double lids_bottom = 0.0;  // frame y below which the cheek wires may act
  // Per vertex: above the mouth (upper lip side). Near the mouth, the side of
  // the nearest lip landmark along the surface (so the lips' inner sheets,
  // which curl past the mouth line, stay with their lip); elsewhere, the side
  // of the mouth line.
  std::vector<char> upper;
  bool upperLip(Eigen::Index v) const { return upper[static_cast<std::size_t>(v)] != 0; }
};
FaceRegions buildFaceRegions(const Mesh& face, const FaceFrame& frame);
// Whether frame x lies on `side` (+1 left, -1 right): disjoint halves, so a sided wire's members meet at the midline without overlap.
inline bool onSide(double x, int side) { return side > 0 ? x >= 0.0 : x < 0.0; }

// The joint of options.joints nearest `point` within `reach` (model units);
// empty: none.
std::string nearestJoint(const MuscleRigOptions& options, const Eigen::Vector3d& point, double reach);

inline double smoothStep(double t) {
  t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
  return t * t * (3.0 - 2.0 * t);
}

// A control moving a cluster (or, with kLocator, a locator) by `offset`
// (model units) at value 1, split over the model axes' translate channels.
void addTranslateDrives(Control& control, const std::string& name, const Eigen::Vector3d& offset,
                        DriveTargetKind kind = DriveTargetKind::kCluster);

// Jaw and eyelid clusters with their controls (jaw_open, blink_L/R, widen_eye_L/R).
void addJawAndLids(ComponentsDocument& doc, const Mesh& face, const FaceFrame& frame, const FaceRegions& regions,
                   const MuscleRigOptions& options);
// Forehead and glabella crease clusters triggered by muscles, and the skull
// sphere the forehead is pushed out of.
void addCreasesAndSkull(ComponentsDocument& doc, const Mesh& face, const FaceFrame& frame, const FaceRegions& regions);
// The eye rig (paper 001, "Eyes" and Figure 4.35): per eye a locator at the
// eyeball's centre aimed at a locator in front of it, both aims children of
// one gaze locator (look_left/right/up/down); the lids around the eye follow
// the gaze; the rig's eye joints (found by position among options.joints)
// aimed the same way; lower-lid clusters (raise_lower_lid_L/R); eyelid
// sculptors pushing lid vertices out of the eyeball along rays from its
// centre.
void addEyes(ComponentsDocument& doc, const Mesh& face, const FaceFrame& frame, const FaceRegions& regions,
             const MuscleRigOptions& options);
// Descriptive controls of Table 6.2 (one per muscle parameter) and the presets.
void addExpressionControls(ComponentsDocument& doc);
void addExpressionPresets(ComponentsDocument& doc);

}  // namespace core::muscle_rig_detail
