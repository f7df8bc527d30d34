// transferRig: the main job, read top to bottom (papers 000 ch. 4.7-4.8, 004
// sec. 5): prepare (cacheable, per source rig) -> warp -> correspond -> dense
// map -> weights -> joints -> shapes -> animations -> attributes -> assemble.
#pragma once

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/transfer/attributes.h"
#include "core/transfer/blendshapes.h"
#include "core/rig/rig.h"
#include "core/transfer/skeleton.h"
#include "core/transfer/skin_weights.h"
#include "core/transfer/transfer_quality.h"
#include "core/correspond/warp_job.h"

namespace core {

// How source deltas (shapes, animated joint translations) are mapped to the target.
enum class ShapeAdaptation {
  kNone,        // raw copy
  kRotation,    // turned by the global rotation between the faces, and scaled by the global
                // scale when that is a change of units or size, not of face shape (default);
                // animated joint translations: the stretch of the dense map's local Jacobian at
                // the joint (papers 000 sec. 4.7.2: proportions adjusted to the target's), turned
                // alike
  kSimilarity,  // rotation and the global uniform scale
  kLocal,       // local Jacobian of the smoothed dense map: follows proportions
};

// "none", "rotation", "similarity", "local" (the options JSON's spelling).
const char* shapeAdaptationName(ShapeAdaptation adaptation);

struct TransferOptions {
  WarpOptions warp;
  bool weights = true;
  bool joints = true;
  bool shapes = true;
  bool animations = true;
  bool attributes = true;          // labels, fields, colours
  // Replace the target's UV sets with the source's (transferUvLayout): target
  // vertices where a seam crosses are split, copies appended.
  bool uvs = false;
  SkinWeightOptions weight_options;
  ShapeAdaptation adaptation = ShapeAdaptation::kRotation;
  // kRotation/kSimilarity: a global rotation below this angle (degrees) is
  // read as face-shape variation (an identity's tilt), not a pose, and not
  // applied to deltas. Measured: ICT identities tilt up to ~4 degrees while
  // their expressions stay unrotated.
  double min_rotation_deg = 6.0;
  // A face shaped differently can feign a rotation about as large as the
  // angle whose tangent is the landmarks' non-rigid residual (relative to
  // their spread): ICT identities exaggerated 3x "tilt" 2-11 degrees with a
  // residual angle of 10-11. A rotation below this factor times that angle
  // is read as shape too (0: only min_rotation_deg counts).
  double shape_rotation_factor = 1.5;
  // kRotation: the global scale is applied too when it is at least this
  // ratio away from 1 (either way): a target in other units or a scaled copy.
  // Closer to 1 it is read as face size, which ICT identities' deltas do not
  // follow (measured: 0.93-1.04 at 1x, 0.78 for an identity exaggerated 3x).
  double min_scale_ratio = 1.5;
  // The two floors above (min_rotation_deg, min_scale_ratio) hold in full for
  // a face whose landmarks miss the similarity by this residual angle or more
  // (ICT identities: 2.8-3.7 degrees); below it they shrink in proportion, so
  // that a copy of the source's shape (residual 0) is turned and scaled by any
  // similarity, however small. 0: the floors always hold in full.
  double shape_residual_deg = 1.0;
  // kRotation: a target whose landmarks (8 or more) are an affine map of the
  // source's stretched at least this ratio more along one axis than another,
  // and by more than shape_stretch_factor times the map's misfit can feign
  // (log ratio against the rms misfit per remaining degree of freedom over
  // the landmarks' thinnest principal spread), has its deltas and animated
  // joint translations mapped by that affine map (a face twice as wide:
  // twice as far sideways). The ratio floor shrinks like the ones above for
  // a near affine copy of the source (misfit angle under
  // shape_residual_deg). ICT identities: ratios 1.03-1.16 (1.53 exaggerated
  // 3x), log ratio at most 1.5 times their misfit. 0: never.
  double min_stretch_ratio = 1.5;
  double shape_stretch_factor = 3.0;
  // kLocal: regularisation of the smoothed map, fraction of the source diagonal.
  double local_smoothing = 0.5;
  // Movement exaggeration (papers 000 sec. 5.4.2): shapes' deltas, and the
  // skin joints' animated motion away from rest (translation offsets,
  // rotation angles, scale ratios in log scale).
  double exaggeration = 1.0;
  std::map<std::string, double> shape_exaggeration;  // by morph target name
  std::map<std::string, double> joint_exaggeration;  // by joint name
  bool diagnostic_attributes = false;             // add _CONFIDENCE, _INPAINTED and _QUALITY to the output
  // The transfer checks its own output (checkTransferQuality): shape
  // outliers and vertices located across an opening are reported (and
  // warned about) always; with strict they fail the transfer
  // (ErrorCode::kQualityGate) naming the shapes and vertex counts.
  QualityOptions quality;
  bool strict = false;
  // Vertices of low confidence that the check finds moving as none of their
  // ring does have their deltas inpainted from their neighbours (then
  // checked again); false: reported only.
  bool repair_unsure = true;
  int threads = 0;
  // Called at each stage boundary with the stage about to run ("warp",
  // "dense_map", "weights", "joints", "animations", "shapes", "attributes") and the fraction
  // of the transfer done (0-1). Returning false stops the transfer there with
  // ErrorCode::kCancelled (cancellation, time limits). Empty = run to the end.
  std::function<bool(std::string_view stage, double fraction)> on_stage;
};

struct PreparedRig {
  Rig rig;
  PreparedSource surface;
  std::optional<SourceUvLayout> uv_layout;  // when the rig has UV sets (for TransferOptions::uvs)
  std::size_t memoryBytes() const;
};

Result<PreparedRig> prepareRig(Rig rig, LandmarkSet landmarks, const std::string& label,
                               const PrepareOptions& options = {});

struct TransferReport {
  WarpReport warp;
  int inpainted_vertices = 0;
  int pruned_vertices = 0;
  int max_influences = 0;
  int shapes = 0;
  int joints = 0;
  int animations = 0;
  int unlocated_vertices = 0;     // target vertices with no location on the source
  // With `uvs`: vertices added where a source UV seam crosses the target
  // (copies of target vertices, after the target's own), and vertices whose
  // UVs extend one side of a seam past it.
  int uv_seam_vertices = 0;
  int uv_extended_vertices = 0;
  // The adaptation deltas were mapped by (TransferOptions::adaptation) and
  // why: the options' choice. rigport does not switch it by itself: no
  // measure of the faces found tells a stylised face, whose deltas follow
  // the stylisation ("local"), from an identity, whose deltas do not
  // (docs/journal/ACCURACY_HISTORY_TARGETS.md, "Stylised faces").
  std::string adaptation;
  std::string adaptation_reason;
  double global_scale = 1.0;      // similarity scale source -> target landmarks
  double global_rotation_deg = 0.0;  // similarity rotation source -> target landmarks
  // The angle a rotation must reach to be applied: min_rotation_deg (shrunk
  // for a near copy of the source, see shape_residual_deg), or
  // shape_rotation_factor times the landmarks' residual angle when larger.
  double rotation_threshold_deg = 0.0;
  bool rotation_applied = false;     // deltas turned (global_rotation_deg >= rotation_threshold_deg)
  bool scale_applied = false;        // deltas scaled (kSimilarity, or kRotation beyond min_scale_ratio, shrunk alike)
  // kRotation: largest over smallest singular value of the landmarks' affine
  // map (1 when not measured), the ratio it had to reach, and whether deltas
  // were mapped by it (min_stretch_ratio); then the rotation and scale above
  // are not applied on their own.
  double stretch_ratio = 1.0;
  double stretch_threshold = 0.0;
  bool stretch_applied = false;
  // The factor applied to deltas: global_scale, or (kRotation) the power of
  // ten within 10% of it when the rest could be face size (a change of
  // units); 1 when not applied.
  double delta_scale = 1.0;
  QualityReport quality;           // the output's own check (checkTransferQuality)
  std::vector<std::string> warnings;
  // milliseconds
  double prepare_ms = 0.0;
  double dense_map_ms = 0.0;
  double weights_ms = 0.0;
  double joints_ms = 0.0;
  double shapes_ms = 0.0;
  double animations_ms = 0.0;
  double attributes_ms = 0.0;
  double quality_ms = 0.0;
  double total_ms = 0.0;
};

struct TransferResult {
  Rig rig;
  TransferReport report;
};

Result<TransferResult> transferRig(const PreparedRig& source, const Mesh& target, const LandmarkSet& target_landmarks,
                                   const std::string& target_label, const TransferOptions& options = {});

}  // namespace core
