// The rig rebuilt on the fitted mesh by vertex index (paper 001 4.3: "the
// reference facial rig can then be rebuilt ... as it is parameterized on the
// topology only"): topology, vertex order, UVs, weights and attributes are
// the reference's; positions are the fit's; joints move through the fit's
// dense map; deltas and animated translations are carried into the output's
// frame and units.
#include <string>
#include <vector>

#include "core/fit/fit_stages.h"
#include "core/transfer/components_transfer.h"
#include "core/transfer/skeleton.h"

namespace core {

namespace {

// The dense map reference -> output: the reference's dense-map centres (its
// landmarks, then its sampled vertices) to where the fit put them.
// `to_output`: the linear part of the map from the reference's frame to the
// output's (the alignment's scale and rotation in the scan's frame).
Result<TpsWarp> fittedDenseMap(const PreparedSource& surface, const Eigen::MatrixX3d& rest,
                               const Eigen::MatrixX3d& output, const Eigen::Matrix3d& to_output) {
  if (!surface.dense_factorization) {
    return Error{ErrorCode::kInvalidArgument, surface.label + ": prepared without dense-map centres; the fit needs them"};
  }
  const Eigen::Index nl = surface.landmark_positions.rows();
  Eigen::MatrixX3d targets(surface.dense_centres.rows(), 3);
  for (Eigen::Index l = 0; l < nl; ++l) {
    // A landmark off a vertex moves with its vertex (its offset carried into
    // the output's frame and units).
    const int v = surface.landmark_vertices[static_cast<std::size_t>(l)];
    targets.row(l) = output.row(v) + (surface.landmark_positions.row(l) - rest.row(v)) * to_output.transpose();
  }
  for (std::size_t i = 0; i < surface.dense_vertices.size(); ++i) {
    targets.row(nl + static_cast<Eigen::Index>(i)) = output.row(surface.dense_vertices[i]);
  }
  return surface.dense_factorization->fit(targets);
}

}  // namespace

Result<Rig> rebuildRig(const FitReference& reference, const FrameMap& frame, const Eigen::MatrixX3d& fitted,
                       double unit_scale, const FitOptions& options, FitReport& report,
                       std::optional<ComponentsDocument>& components) {
  const PreparedRig& prepared = *reference.rig;
  const Mesh& rest_mesh = prepared.surface.mesh;
  const bool scan_frame = options.frame == FitFrame::kScan;
  const Similarity& s = frame.reference_to_scan;
  Eigen::MatrixX3d output = fitted;
  if (scan_frame) {
    for (Eigen::Index v = 0; v < output.rows(); ++v) output.row(v) = frame.toScan(fitted.row(v).transpose()).transpose();
  }
  // The alignment's rotation, not the fitted face's: neither can tell the
  // head's pose from the identity's own tilt (docs/FIT.md "Deltas").
  const Eigen::Matrix3d rotation = scan_frame ? s.rotation : Eigen::Matrix3d::Identity();
  // Deltas: the reference's, turned into the scan's frame and in its units;
  // never scaled by the head's size (an identity's lips open as far).
  Eigen::Matrix3d deltas = Eigen::Matrix3d::Identity();
  const TransferOptions& rebuild = options.rebuild;
  switch (rebuild.adaptation) {
    case ShapeAdaptation::kNone: break;
    case ShapeAdaptation::kRotation: deltas = (scan_frame ? unit_scale : 1.0) * rotation; break;
    case ShapeAdaptation::kSimilarity: deltas = (scan_frame ? s.scale : s.scale / unit_scale) * rotation; break;
    case ShapeAdaptation::kLocal: break;  // per vertex below
  }

  Rig rig = prepared.rig;
  rig.mesh.positions = output;
  rig.mesh.normals = computeSharedVertexNormals(output, rest_mesh.triangles,
                                                smoothVertexRepresentatives(rest_mesh.positions, rest_mesh.normals));
  const Eigen::Matrix3d to_output = scan_frame ? Eigen::Matrix3d(s.scale * s.rotation) : Eigen::Matrix3d::Identity();
  auto dense_map = fittedDenseMap(prepared.surface, rest_mesh.positions, output, to_output);
  if (!dense_map) return dense_map.error();

  // kLocal: deltas by the Jacobian of the dense map smoothed, as a transfer
  // maps them (the face's per vertex; animations and parts at their points).
  std::vector<Eigen::Matrix3d> local;
  std::optional<TpsWarp> smooth_map;
  if (rebuild.adaptation == ShapeAdaptation::kLocal) {
    TpsOptions smooth;
    smooth.regularization = rebuild.local_smoothing * prepared.surface.diagonal;
    smooth.leave_one_out = false;
    auto smoothed = fitTps(prepared.surface.dense_centres, dense_map->apply(prepared.surface.dense_centres), smooth);
    if (!smoothed) return smoothed.error();
    local = smoothed->jacobians(rest_mesh.positions);
    smooth_map = std::move(*smoothed);
  }
  const auto adaptation = [&](const Eigen::Vector3d& p) -> Eigen::Matrix3d {
    return smooth_map ? smooth_map->jacobian(p) : deltas;
  };
  if (rebuild.shapes) {
    for (MorphTarget& t : rig.morph_targets) {
      if (local.empty()) {
        t.position_deltas = t.position_deltas * deltas.transpose();
      } else {
        for (Eigen::Index v = 0; v < t.position_deltas.rows(); ++v) {
          t.position_deltas.row(v) = (local[static_cast<std::size_t>(v)] * t.position_deltas.row(v).transpose()).transpose();
        }
      }
      if (t.normal_deltas.rows() > 0) t.normal_deltas = t.normal_deltas * rotation.transpose();
    }
    report.shapes = static_cast<int>(rig.morph_targets.size());
  } else {
    rig.morph_targets.clear();
    rig.morph_default_weights.resize(0);
    rig.baked_presets.clear();
  }
  if (rebuild.joints && rig.skin) {
    TransferredSkeleton skeleton = transferSkeleton(prepared.rig, *dense_map, rotation);
    rig.nodes = std::move(skeleton.nodes);
    rig.skin = std::move(skeleton.skin);
    report.joints = skeleton.moved_nodes;
  }
  if (!rebuild.weights) {
    rig.skin.reset();
    rig.weights = SkinWeights();
  }
  if (rebuild.animations) {
    rig.animations = transferAnimations(prepared.rig, rig.nodes, rotation, adaptation);
    report.animations = static_cast<int>(rig.animations.size());
  } else {
    rig.animations.clear();
  }
  if (!rebuild.attributes) rig.attributes = VertexAttributes{};
  // The rig's other meshes by vertex index through the same dense map.
  CarriedParts parts = carryParts(prepared.rig.parts, *dense_map, adaptation, rotation);
  rig.parts = std::move(parts.parts);
  dropPartChannels(rig.parts, rebuild.shapes, rig.skin.has_value());
  report.parts = std::move(parts.report);
  // The components document by vertex index (001 4.3); its lengths follow
  // the head's size, as the similarity adaptation's deltas do.
  if (prepared.components) {
    components = rebuildComponents(*prepared.components, *dense_map, rotation,
                                   scan_frame ? s.scale : s.scale / unit_scale);
  }
  return rig;
}

}  // namespace core
