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

#include "core/base/stage_hook.h"
#include "core/transfer/attributes.h"
#include "core/components/components.h"
#include "core/transfer/blendshapes.h"
#include "core/transfer/parts.h"
#include "core/transfer/parts_occlusion.h"
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
  WarpOptions warp;                // the correspondence
  bool weights = true;             // skin weights
  bool joints = true;              // joints (moved through the dense map)
  bool shapes = true;              // blend shapes
  bool animations = true;          // animations
  bool attributes = true;          // labels, fields, colours
  // Replace the target's UV sets with the source's (transferUvLayout): vertices where a seam crosses are split.
  bool uvs = false;
  SkinWeightOptions weight_options;  // influences kept, inpainting
  ShapeAdaptation adaptation = ShapeAdaptation::kRotation;  // how deltas and joint translations are mapped
  // kRotation/kSimilarity: a global rotation below this (degrees) is read as face shape, not a pose: not applied.
  double min_rotation_deg = 6.0;
  // ... nor one below this factor times the landmarks' residual angle (misfit over spread) (0: only the above).
  double shape_rotation_factor = 1.5;
  // kRotation: the global scale is applied too when at least this ratio away from 1 (units, a scaled copy).
  double min_scale_ratio = 1.5;
  // Below this landmark residual angle (degrees) the two floors above shrink in proportion. 0: they always hold.
  double shape_residual_deg = 1.0;
  // kRotation: deltas follow the landmarks' (8+) affine map when it stretches this ratio more on one axis. 0: never.
  double min_stretch_ratio = 1.5;
  // ... and its log stretch ratio exceeds this many times what the affine fit's misfit can feign.
  double shape_stretch_factor = 3.0;
  // kLocal: regularisation of the smoothed map, fraction of the source diagonal.
  double local_smoothing = 0.5;
  // Movement exaggeration (papers 000 sec. 5.4.2): gain on shapes' deltas and skin joints' motion away from rest.
  double exaggeration = 1.0;
  std::map<std::string, double> shape_exaggeration;  // by morph target name
  std::map<std::string, double> joint_exaggeration;  // by joint name
  bool diagnostic_attributes = false;             // add _CONFIDENCE, _INPAINTED and _QUALITY to the output
  QualityOptions quality;          // the output's own check (checkTransferQuality), always run and reported
  // A failed quality check fails the transfer (ErrorCode::kQualityGate) naming the shapes; false: a warning.
  bool strict = false;
  // Low-confidence vertices the check flags get deltas inpainted from neighbours, then rechecked; false: reported.
  bool repair_unsure = true;
  // Before each stage ("warp", "dense_map", "weights", "joints", "animations", "shapes", "attributes"): false cancels.
  StageHook on_stage;
};

struct PreparedRig {
  Rig rig;
  PreparedSource surface;
  std::optional<SourceUvLayout> uv_layout;  // when the rig has UV sets (for TransferOptions::uvs)
  // The rig's components document (docs/COMPONENTS.md), when it has one:
  // carried to each target (core/transfer/components_transfer.h).
  std::optional<ComponentsDocument> components;
  SourcePartsOcclusion parts_occlusion;  // the rig's parts against its own skin (core/transfer/parts_occlusion.h)
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
  std::vector<CarriedPart> parts;  // the rig's other meshes, as carried (core/transfer/parts.h)
  std::vector<std::string> warnings;
  // milliseconds
  double prepare_ms = 0.0;
  double dense_map_ms = 0.0;
  double weights_ms = 0.0;
  double joints_ms = 0.0;
  double shapes_ms = 0.0;
  double parts_ms = 0.0;
  double components_ms = 0.0;  // the components document carried (0 without one)
  double animations_ms = 0.0;
  double attributes_ms = 0.0;
  double quality_ms = 0.0;
  double total_ms = 0.0;
};

struct TransferResult {
  Rig rig;
  TransferReport report;
  std::optional<ComponentsDocument> components;  // the target's, when the rig has a document
};

// The transfer to a target prepared for this job (prepareTarget).
Result<TransferResult> transferRig(const PreparedRig& source, PreparedTarget target, const TransferOptions& options = {});
// The warp options of a transfer: the output is the target rigged, not the
// guide, so only what the transfer reads from the guide is projected.
WarpOptions transferWarpOptions(const TransferOptions& options);
// The transfer through a correspondence made by the caller (correspondThroughFit
// with transferWarpOptions).
Result<TransferResult> transferRig(const PreparedRig& source, WarpResult correspondence, const TransferOptions& options = {});
// The same, preparing the target first.
Result<TransferResult> transferRig(const PreparedRig& source, const Mesh& target, const LandmarkSet& target_landmarks,
                                   const std::string& target_label, const TransferOptions& options = {});

}  // namespace core
