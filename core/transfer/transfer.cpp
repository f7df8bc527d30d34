#include <Eigen/LU>
#include <Eigen/SVD>

#include "core/transfer/transfer.h"

#include "core/base/timing.h"
#include "core/transfer/components_transfer.h"
#include "core/transfer/materials.h"
#include "core/transfer/parts_occlusion.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include "core/solve/inpainting.h"
#include "core/geometry/similarity.h"

namespace core {

namespace {

// The power of ten (metres, centimetres, millimetres...) within 10% of
// `scale`, else 0. Inches and feet are left out on purpose: their ratios
// (2.54, 0.254, 0.3048) sit next to scales a copy is plausibly made with.
double unitRatioNear(double scale) {
  if (!(scale > 0.0)) return 0.0;
  const double unit = std::pow(10.0, std::round(std::log10(scale)));
  return std::abs(std::log(scale / unit)) <= std::log(1.1) ? unit : 0.0;
}

// The one matrix the default (kRotation) and kSimilarity adaptations map
// every delta and animated joint translation by, and the rotation the
// joints' frames turn by, decided from the landmarks alone (source
// landmarks and their images under the landmark warp). Fills the report's
// global_*, rotation_*, scale_*, delta_scale and stretch_* fields and
// warnings.
struct GlobalAdaptation {
  Eigen::Matrix3d deltas = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
};

// TEXCOORD_0 (when the mesh has it) and the extra UV sets, in that order.
std::vector<Eigen::MatrixX2d> sourceUvSets(const Rig& rig) {
  std::vector<Eigen::MatrixX2d> sets;
  if (rig.mesh.uvs.rows() > 0) sets.push_back(rig.mesh.uvs);
  sets.insert(sets.end(), rig.attributes.extra_uv_sets.begin(), rig.attributes.extra_uv_sets.end());
  return sets;
}

GlobalAdaptation globalAdaptation(const Eigen::MatrixX3d& src_landmarks, const Eigen::MatrixX3d& tgt_landmarks,
                                  const TransferOptions& options, const std::string& target_label,
                                  TransferReport& report) {
  constexpr double kDegrees = 180.0 / std::numbers::pi;
  auto angleOf = [&](const Eigen::Matrix3d& r) {
    return std::acos(std::clamp((r.trace() - 1.0) / 2.0, -1.0, 1.0)) * kDegrees;
  };
  const Similarity similarity = fitSimilarity(src_landmarks, tgt_landmarks);
  report.global_scale = similarity.scale;
  report.global_rotation_deg = angleOf(similarity.rotation);
  // Residual angle: atan of the landmarks' rms misfit after the similarity
  // (in source units) over their rms spread about their centroid.
  const Eigen::MatrixX3d centred = src_landmarks.rowwise() - src_landmarks.colwise().mean();
  const auto n = static_cast<double>(src_landmarks.rows());
  const double spread = std::sqrt(centred.rowwise().squaredNorm().mean());
  const double residual_deg =
      spread > 0.0 && similarity.scale > 0.0 ? std::atan(similarity.rms_residual / (similarity.scale * spread)) * kDegrees
                                             : 0.0;
  // The floors (min_rotation_deg, min_scale_ratio, min_stretch_ratio) are
  // for faces shaped otherwise than the source, whose identity tilts, sizes
  // and stretches them; a copy of the source's shape has none, so they
  // shrink with its residual below shape_residual_deg: a copy is turned,
  // scaled (and stretched) by any map, however slight. Rounding-level
  // rotations and scales (an untransformed copy) stay unapplied.
  auto floorShare = [&](double angle_deg) {
    return options.shape_residual_deg > 0.0 ? std::min(1.0, angle_deg / options.shape_residual_deg) : 1.0;
  };
  constexpr double kRoundingDeg = 1e-4, kRoundingLogScale = 1e-9;
  auto rotationThreshold = [&](double angle_deg) {
    return std::max({floorShare(angle_deg) * options.min_rotation_deg, options.shape_rotation_factor * angle_deg,
                     kRoundingDeg});
  };

  // A face stretched as a whole (an affine map of the source's shape: twice
  // as wide) takes its deltas stretched the same way, the landmarks' affine
  // map being the local deformation everywhere. An identity is no such map:
  // its landmarks miss the best affine fit, and the anisotropy its shape
  // feigns stays within about that misfit. The misfit is taken relative to
  // the landmarks' thinnest principal spread (where the fit is least sure of
  // the stretch) and per degree of freedom the fit leaves (n - 4 of n per
  // coordinate): ICT identities, also exaggerated 3x, the cartoon and random
  // draws of 8-20 landmarks have log anisotropy at most 1.7x that misfit; an
  // identity stretched 1.6x sideways 4.0x, a stretched copy of the source
  // without bound. Under kMinStretchLandmarks the fit has too few spare
  // equations to tell (draws of 4-6 ICT landmarks on identities "fit"
  // stretches up to 2.1x). The map splits into a rotation and a stretch
  // (polar decomposition): the rotation turns the joints' frames and the
  // deltas when it is a pose, by the rule below with the affine map's
  // misfit for the residual; the stretch always applies.
  constexpr Eigen::Index kMinStretchLandmarks = 8;
  std::optional<AffineMap> affine;
  if (options.adaptation == ShapeAdaptation::kRotation && options.min_stretch_ratio > 0.0 &&
      src_landmarks.rows() >= kMinStretchLandmarks && spread > 0.0) {
    affine = fitAffine(src_landmarks, tgt_landmarks);
  }
  if (affine && affine->linear.determinant() > 0.0) {
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(affine->linear, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Vector3d sv = svd.singularValues();
    const double size = std::cbrt(affine->linear.determinant());
    const double thinnest =
        std::sqrt(Eigen::JacobiSVD<Eigen::Matrix3d>(centred.transpose() * centred / n).singularValues()(2));
    if (sv(2) > 0.0 && thinnest > 0.0) {
      report.stretch_ratio = sv(0) / sv(2);
      const double misfit = affine->rms_residual * std::sqrt(n / (n - 4.0)) / (size * thinnest);
      const double threshold =
          std::max({options.min_stretch_ratio > 1.0
                        ? floorShare(std::atan(misfit) * kDegrees) * std::log(options.min_stretch_ratio)
                        : 0.0,
                    options.shape_stretch_factor * misfit, kRoundingLogScale});
      report.stretch_threshold = std::exp(threshold);
      report.stretch_applied = std::log(report.stretch_ratio) >= threshold;
    }
    if (report.stretch_applied) {
      const Eigen::Matrix3d rotation = svd.matrixU() * svd.matrixV().transpose();  // det +1: det(linear) > 0
      const Eigen::Matrix3d stretch = rotation.transpose() * affine->linear;      // symmetric positive
      const double affine_residual_deg = std::atan(affine->rms_residual / (size * spread)) * kDegrees;
      report.global_rotation_deg = angleOf(rotation);
      report.rotation_threshold_deg = rotationThreshold(affine_residual_deg);
      report.rotation_applied = report.global_rotation_deg >= report.rotation_threshold_deg;
      char ratio[32];
      std::snprintf(ratio, sizeof ratio, "%.3g", report.stretch_ratio);
      if (!report.warp.landmarks_misfit) report.warnings.push_back(target_label + " is the source's shape stretched (" + ratio +
                                "x more along one axis than another): its deltas and animated joint translations "
                                "were mapped by the landmarks' affine map");
      GlobalAdaptation out;
      if (report.rotation_applied) out.rotation = rotation;
      out.deltas = out.rotation * stretch;
      return out;
    }
  }

  GlobalAdaptation out;
  report.rotation_threshold_deg = rotationThreshold(residual_deg);
  report.rotation_applied = report.global_rotation_deg >= report.rotation_threshold_deg;
  if (report.rotation_applied) out.rotation = similarity.rotation;
  const double log_scale = similarity.scale > 0.0 ? std::abs(std::log(similarity.scale)) : 0.0;
  const double scale_threshold = std::max(
      options.min_scale_ratio > 1.0 ? floorShare(residual_deg) * std::log(options.min_scale_ratio) : 0.0,
      kRoundingLogScale);
  report.scale_applied =
      options.adaptation == ShapeAdaptation::kSimilarity ||
      (options.adaptation == ShapeAdaptation::kRotation && options.min_scale_ratio > 0.0 && similarity.scale > 0.0 &&
       log_scale >= scale_threshold);
  double delta_scale = report.scale_applied ? similarity.scale : 1.0;
  if (report.scale_applied && options.adaptation == ShapeAdaptation::kRotation) {
    // A scale within 10% of a power of ten is that change of units when the
    // rest could be face size, which the deltas do not follow.
    const double unit = unitRatioNear(similarity.scale);
    const bool units = unit > 0.0 && std::abs(std::log(similarity.scale / unit)) < scale_threshold;
    if (units) delta_scale = unit;
    char measured[32], applied[32];
    std::snprintf(measured, sizeof measured, "%.4g", similarity.scale);
    std::snprintf(applied, sizeof applied, "%.4g", delta_scale);
    if (!report.warp.landmarks_misfit) report.warnings.push_back(target_label + " is " + measured + " times the size of the source (" +
                              (units ? "other units" : "a scaled copy") +
                              "): its deltas and animated joint translations were scaled by " + applied);
  }
  report.delta_scale = delta_scale;
  out.deltas = delta_scale * out.rotation;
  return out;
}

// Names `option` gives gains for that the rig has no `what` of: a typo
// ("JawOpen") or an options file shared across rigs. A warning each, with the
// rig's name that differs only in case when there is one.
void warnUnknownNames(const std::map<std::string, double>& gains, const std::vector<std::string>& names,
                      const std::string& option, const std::string& what, std::vector<std::string>& warnings) {
  auto lower = [](std::string text) {
    std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return text;
  };
  for (const auto& entry : gains) {
    const std::string& name = entry.first;  // a plain reference: clang 14 cannot capture structured bindings
    if (std::find(names.begin(), names.end(), name) != names.end()) continue;
    std::string message = option + " names '" + name + "', but the rig has no " + what + " of that name; ignored";
    const auto same = std::find_if(names.begin(), names.end(), [&](const std::string& n) { return lower(n) == lower(name); });
    if (same != names.end()) message += " (did you mean '" + *same + "'?)";
    warnings.push_back(std::move(message));
  }
}


// Names in the exaggeration maps that the rig does not have: a typo must not
// go unnoticed.
void warnUnknownExaggerations(const Rig& src, const TransferOptions& options, TransferReport& report) {
  if (options.shapes) {
    std::vector<std::string> shape_names;
    for (const auto& t : src.morph_targets) shape_names.push_back(t.name);
    warnUnknownNames(options.shape_exaggeration, shape_names, "shape_exaggeration", "morph target", report.warnings);
  }
  if (options.animations) {
    std::vector<std::string> node_names;
    for (const auto& n : src.nodes) node_names.push_back(n.name);
    warnUnknownNames(options.joint_exaggeration, node_names, "joint_exaggeration", "joint", report.warnings);
  }
}

// What the dense map gives every later stage: the global similarity, the
// adaptation of deltas at a point (TransferOptions::adaptation) and per target
// vertex (one matrix for all unless local).
struct DenseMapAdaptation {
  const TpsWarp& dense_map;  // the warp's dense map, or its landmark warp without one
  GlobalAdaptation global;
  ShapeAdaptation mode = ShapeAdaptation::kRotation;
  std::optional<TpsWarp> smooth_map;  // kLocal: the dense map smoothed
  std::vector<Eigen::Matrix3d> vertex_adaptation;

  Eigen::Matrix3d at(const Eigen::Vector3d& p) const {
    switch (mode) {
      case ShapeAdaptation::kNone: return Eigen::Matrix3d::Identity();
      case ShapeAdaptation::kRotation:
      case ShapeAdaptation::kSimilarity: return global.deltas;
      case ShapeAdaptation::kLocal: return smooth_map->jacobian(p);
    }
    return Eigen::Matrix3d::Identity();
  }
  // Animated joint translations keep the source's proportions adjusted to the
  // target's (papers 000 sec. 4.7.2: a jaw thrust on a face a third larger
  // moves a third farther): by default the stretch of the dense map's local
  // Jacobian at the joint (its polar factor), turned by the global rotation
  // when that is a pose, so that keys and joint frames turn alike.
  Eigen::Matrix3d jointAt(const Eigen::Vector3d& p) const {
    if (mode != ShapeAdaptation::kRotation) return at(p);
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(dense_map.jacobian(p), Eigen::ComputeFullV);
    return global.rotation * svd.matrixV() * svd.singularValues().asDiagonal() * svd.matrixV().transpose();
  }
};

Result<DenseMapAdaptation> adaptToDenseMap(const PreparedRig& source, const WarpResult& warp,
                                           const TransferOptions& options, const std::string& target_label,
                                           TransferReport& report) {
  const Eigen::MatrixX3d& src_landmarks = warp.landmark_pairs.source;
  Eigen::MatrixX3d tgt_landmarks(src_landmarks.rows(), 3);
  for (Eigen::Index i = 0; i < src_landmarks.rows(); ++i) {
    tgt_landmarks.row(i) = warp.landmark_warp.apply(Eigen::Vector3d(src_landmarks.row(i).transpose())).transpose();
  }
  DenseMapAdaptation adaptation{warp.dense_map ? *warp.dense_map : warp.landmark_warp,
                                globalAdaptation(src_landmarks, tgt_landmarks, options, target_label, report),
                                options.adaptation, std::nullopt, {}};
  report.adaptation = shapeAdaptationName(options.adaptation);
  report.adaptation_reason =
      options.adaptation == ShapeAdaptation::kRotation
          ? "the default: deltas as the rig's, turned, scaled or stretched only for a pose, other units or a face "
            "stretched as a whole; a stylised face whose shapes should follow its stylisation takes \"local\""
          : "set in the options";
  if (options.adaptation != ShapeAdaptation::kLocal) {
    adaptation.vertex_adaptation = {adaptation.at(Eigen::Vector3d::Zero())};
    return adaptation;
  }
  TpsOptions smooth;
  smooth.regularization = options.local_smoothing * source.surface.diagonal;
  smooth.leave_one_out = false;
  auto fitted = fitTps(source.surface.dense_centres, adaptation.dense_map.apply(source.surface.dense_centres), smooth);
  if (!fitted) return fitted.error();
  adaptation.smooth_map = std::move(*fitted);
  const Mesh& src_mesh = source.surface.mesh;
  const Eigen::Index nt = warp.target.mesh.vertexCount();
  Eigen::MatrixX3d at(nt, 3);
  for (Eigen::Index v = 0; v < nt; ++v) {
    const SurfacePoint& sp = warp.locations.on_source[static_cast<std::size_t>(v)];
    at.row(v) = sp.found() ? interpolateOnFace(src_mesh.positions, src_mesh.triangles, sp.face, sp.barycentric)
                           : Eigen::RowVector3d::Zero();
  }
  adaptation.vertex_adaptation = adaptation.smooth_map->jacobians(at);
  return adaptation;
}

// One graph Laplacian of the target for every stage that inpaints untrusted
// vertices (mismatched vertices are also low-confidence), and one
// factorisation of the mismatched split for shapes and attributes. Cut
// across the openings' sides: a lip takes values from its own side only.
struct TargetInpainting {
  Eigen::SparseMatrix<double> laplacian;      // empty when every vertex is trusted
  std::optional<HarmonicInpainting> mismatched;
  const HarmonicInpainting* mismatchedOrNull() const { return mismatched ? &*mismatched : nullptr; }
};

Result<TargetInpainting> targetInpainting(const Rig& src, const WarpResult& warp, const TransferOptions& options,
                                          const std::string& target_label) {
  const Mesh& target = warp.target.mesh;
  const TargetLocations& locations = warp.locations;
  TargetInpainting out;
  if (locations.low_confidence > 0) {
    out.laplacian = uniformLaplacian(target.triangles, target.vertexCount(), warp.target.representative);
    if (options.warp.side_matching && !warp.target_sides.empty()) cutAcrossSides(out.laplacian, warp.target_sides);
  }
  const bool attributes_inpainted =
      options.attributes && (src.attributes.colors.rows() > 0 || !src.attributes.fields.empty());
  if (locations.mismatched.any() && ((options.shapes && !src.morph_targets.empty()) || attributes_inpainted)) {
    std::vector<char> known(static_cast<std::size_t>(target.vertexCount()));
    for (Eigen::Index v = 0; v < target.vertexCount(); ++v) known[static_cast<std::size_t>(v)] = locations.mismatched(v) == 0;
    auto created = HarmonicInpainting::create(out.laplacian, known);
    if (!created) return Error{created.error().code, target_label + ": inpainting mismatched vertices: " + created.error().message};
    out.mismatched = std::move(*created);
  }
  return out;
}

std::vector<Animation> transferJointAnimations(const Rig& src, const std::vector<Node>& moved_nodes, bool joints_moved,
                                               const DenseMapAdaptation& adaptation, const TransferOptions& options) {
  const AnimationTransferOptions animation_options{{options.exaggeration, options.joint_exaggeration}};
  if (!joints_moved) {
    const auto unchanged = [](const Eigen::Vector3d&) -> Eigen::Matrix3d { return Eigen::Matrix3d::Identity(); };
    return transferAnimations(src, src.nodes, Eigen::Matrix3d::Identity(), unchanged, animation_options);
  }
  const auto joint_adaptation = [&adaptation](const Eigen::Vector3d& p) { return adaptation.jointAt(p); };
  return transferAnimations(src, moved_nodes, adaptation.global.rotation, joint_adaptation, animation_options);
}

void transferShapes(const PreparedRig& source, const TargetLocations& locations,
                    const std::vector<Eigen::Matrix3d>& vertex_adaptation, const HarmonicInpainting* mismatched,
                    const TransferOptions& options, Rig& out) {
  const Rig& src = source.rig;
  if (options.shapes) {
    const ShapeTransferOptions shape_options{{options.exaggeration, options.shape_exaggeration}};
    out.morph_targets = transferMorphTargets(src.morph_targets, source.surface.mesh.triangles, locations,
                                             vertex_adaptation, out.mesh, mismatched, shape_options);
    out.morph_default_weights = src.morph_default_weights;
    out.baked_presets = src.baked_presets;
    return;
  }
  // Morph-weight channels would point at targets that no longer exist.
  for (auto& a : out.animations) {
    std::erase_if(a.channels, [](const AnimationChannel& c) { return c.path == AnimationPath::kWeights; });
  }
  std::erase_if(out.animations, [](const Animation& a) { return a.channels.empty(); });
}

// The output's worst vertices, before any UV copies. A vertex of low
// confidence moving as none of its ring does took its location's values from
// the wrong place (the other lip, the other side of the columella): its
// deltas are inpainted from its neighbours, as a mismatched vertex's are, and
// the output checked again. Strict: a check that still fails fails the job.
Status checkAndRepairShapes(const PreparedRig& source, const WarpResult& warp,
                            const Eigen::SparseMatrix<double>& laplacian, const TransferOptions& options, Rig& out,
                            TransferReport& report) {
  const Mesh& target = warp.target.mesh;
  const TargetLocations& locations = warp.locations;
  const std::string& target_label = warp.target.label;
  QualityOptions quality_options = options.quality;
  const QualitySource quality_source{source.surface.mesh.triangles, source.surface.adjacency,
                                     source.surface.vertex_sides, source.rig.morph_targets};
  report.quality = checkTransferQuality(target, warp.target.adjacency, out.morph_targets, locations,
                                        warp.target_sides, quality_source, quality_options);
  if (options.repair_unsure && !report.quality.clean() && !out.morph_targets.empty() && laplacian.rows() > 0) {
    std::vector<char> known(static_cast<std::size_t>(target.vertexCount()), 1);
    int repaired = 0;
    for (Eigen::Index v = 0; v < target.vertexCount(); ++v) {
      const bool unsure = report.quality.per_vertex(v) > 0.0 && locations.confidence(v) == 0.0;
      known[static_cast<std::size_t>(v)] = locations.mismatched(v) == 0 && !unsure;
      repaired += unsure && locations.mismatched(v) == 0 ? 1 : 0;
    }
    if (repaired > 0) {
      auto repair = HarmonicInpainting::create(laplacian, known);
      if (!repair) return Error{repair.error().code, target_label + ": inpainting unsure vertices: " + repair.error().message};
      inpaintShapeDeltas(*repair, out.morph_targets);
      updateNormalDeltas(out.mesh, out.morph_targets);
      report.quality = checkTransferQuality(target, warp.target.adjacency, out.morph_targets, locations,
                                            warp.target_sides, quality_source, quality_options);
      report.quality.repaired_vertices = repaired;
    }
  }
  if (!report.quality.clean()) {
    if (options.strict) {
      return makeError(ErrorCode::kQualityGate, target_label + ": the transfer failed its quality check (strict): " +
                                                    report.quality.summary());
    }
    report.warnings.push_back(target_label + ": unsure vertices, check them before use: " + report.quality.summary());
  }
  return Ok{};
}

void addDiagnosticAttributes(const TargetLocations& locations, const TransferredWeights& weights,
                             const QualityReport& quality, Rig& out) {
  const Eigen::Index nt = out.mesh.vertexCount();
  out.attributes.fields["CONFIDENCE"] = locations.confidence;
  out.attributes.fields["INPAINTED"] = weights.inpainted.size() == nt ? weights.inpainted.cast<double>().eval()
                                                                      : Eigen::VectorXd::Zero(nt).eval();
  out.attributes.fields["QUALITY"] = quality.per_vertex;
}

// Last: carrying the source's UV seams over splits target vertices, and
// every per-vertex value before goes with its copies.
Status transferUvs(const PreparedRig& source, const WarpResult& warp, const TransferOptions& options, Rig& out,
                   TransferReport& report, std::optional<ComponentsDocument>& components) {
  if (!options.uvs) return Ok{};
  const std::string& target_label = warp.target.label;
  if (!source.uv_layout) {
    report.warnings.push_back("uvs: " + source.surface.label + " has no UV set to transfer; " + target_label +
                              " keeps its own UVs");
    return Ok{};
  }
  const Mesh& src_mesh = source.surface.mesh;
  auto layout = transferUvLayout(src_mesh, *source.uv_layout, warp.target.mesh, warp.locations, warp.target.representative);
  if (!layout) return Error{layout.error().code, target_label + ": " + layout.error().message};
  if (components) addVertexCopies(*components, layout->copy_of, static_cast<int>(out.mesh.vertexCount()));
  appendVertexCopies(out, layout->copy_of);
  out.mesh.triangles = layout->triangles;
  std::size_t next = 0;
  if (src_mesh.uvs.rows() > 0) out.mesh.uvs = layout->sets[next++];
  out.attributes.extra_uv_sets.assign(layout->sets.begin() + static_cast<std::ptrdiff_t>(next), layout->sets.end());
  report.uv_seam_vertices = static_cast<int>(layout->copy_of.size());
  report.uv_extended_vertices = layout->extended_vertices;
  return Ok{};
}

}  // namespace

const char* shapeAdaptationName(ShapeAdaptation adaptation) {
  switch (adaptation) {
    case ShapeAdaptation::kNone: return "none";
    case ShapeAdaptation::kRotation: return "rotation";
    case ShapeAdaptation::kSimilarity: return "similarity";
    case ShapeAdaptation::kLocal: return "local";
  }
  return "rotation";
}

std::size_t PreparedRig::memoryBytes() const {
  std::size_t bytes = surface.memoryBytes() + (uv_layout ? uv_layout->memoryBytes() : 0);
  for (const auto& t : rig.morph_targets) bytes += static_cast<std::size_t>(t.position_deltas.size() + t.normal_deltas.size()) * sizeof(double);
  bytes += static_cast<std::size_t>(rig.weights.nonZeros()) * (sizeof(double) + sizeof(int));
  for (const auto& a : rig.animations) for (const auto& c : a.channels) bytes += static_cast<std::size_t>(c.values.size() + c.times.size()) * sizeof(double);
  for (const RigPart& part : rig.parts) {  // the other meshes: as large as the face's shapes, together
    bytes += static_cast<std::size_t>(part.mesh.positions.size() + part.mesh.normals.size()) * sizeof(double);
    for (const auto& t : part.morph_targets) bytes += static_cast<std::size_t>(t.position_deltas.size() + t.normal_deltas.size()) * sizeof(double);
    bytes += static_cast<std::size_t>(part.weights.nonZeros()) * (sizeof(double) + sizeof(int));
  }
  if (components) {  // its bulk: member lists and control points
    for (const Cluster& c : components->clusters) bytes += c.members.size() * sizeof(ClusterMember);
    for (const Wire& w : components->wires) bytes += w.members.size() * sizeof(int);
    for (const Lattice& l : components->lattices) bytes += l.members.size() * sizeof(int) + l.points.size() * sizeof(Eigen::Vector3d);
    for (const PushToSurface& p : components->push_to_surfaces) bytes += p.members.size() * sizeof(int) + p.surface.triangles.size() * sizeof(Eigen::Vector3i);
    for (const NurbsCurve& c : components->curves) bytes += c.points.size() * sizeof(Binding);
    for (const NurbsSurface& s : components->surfaces) bytes += s.points.size() * sizeof(Binding);
  }
  return bytes;
}

Result<PreparedRig> prepareRig(Rig rig, LandmarkSet landmarks, const std::string& label, const PrepareOptions& options) {
  if (rig.skin && rig.weights.rows() != rig.mesh.vertexCount()) {
    return makeError(ErrorCode::kInvalidMesh, label + ": skin weights cover " + std::to_string(rig.weights.rows()) +
                                                  " vertices but the mesh has " + std::to_string(rig.mesh.vertexCount()));
  }
  for (const auto& t : rig.morph_targets) {
    if (t.position_deltas.rows() != rig.mesh.vertexCount()) {
      return makeError(ErrorCode::kInvalidMesh, label + ": morph target '" + t.name + "' has the wrong vertex count");
    }
  }
  for (const auto& a : rig.animations) {
    for (std::size_t c = 0; c < a.channels.size(); ++c) {
      if (!a.channels[c].values.allFinite() || !a.channels[c].times.allFinite()) {
        return makeError(ErrorCode::kInvalidMesh, label + ": animation '" + a.name + "' channel " + std::to_string(c) +
                                                      " has non-finite keys");
      }
    }
  }
  // A rig's region labels are its REGION label attribute (the glTF reader
  // reads _REGION into both); without a usable one (0..kMaxRegionLabel, one
  // per vertex) the rig has none.
  const auto regions = rig.attributes.labels.find(kRegionAttribute);
  const bool usable_regions = regions != rig.attributes.labels.end() &&
                              regions->second.size() == rig.mesh.vertexCount() &&
                              firstInvalidRegionLabel(regions->second) < 0;
  rig.mesh.regions = usable_regions ? regions->second : Eigen::VectorXi();
  auto surface = prepareSource(rig.mesh, std::move(landmarks), label, options);
  if (!surface) return surface.error();
  PreparedRig prepared;
  prepared.rig = std::move(rig);
  prepared.rig.mesh.normals = surface->mesh.normals;
  prepared.surface = std::move(*surface);
  const std::vector<Eigen::MatrixX2d> uv_sets = sourceUvSets(prepared.rig);
  if (!uv_sets.empty()) {
    auto uv_layout = prepareUvLayout(prepared.surface.mesh, uv_sets, label);
    if (!uv_layout) return uv_layout.error();
    prepared.uv_layout = std::move(*uv_layout);
  }
  prepared.parts_occlusion = prepareSourcePartsOcclusion(prepared.surface.mesh, prepared.surface.landmark_positions,
                                                         prepared.surface.landmark_vertices, prepared.rig.parts);
  return prepared;
}

Result<TransferResult> transferRig(const PreparedRig& source, const Mesh& target, const LandmarkSet& target_landmarks,
                                   const std::string& target_label, const TransferOptions& options) {
  auto prepared = prepareTarget(target, target_landmarks, target_label);
  if (!prepared) return prepared.error();
  return transferRig(source, std::move(*prepared), options);
}

namespace {

Status checkSourceSkin(const PreparedRig& source, const TransferOptions& options) {
  if ((options.weights || options.joints) && !source.rig.skin) {
    return makeError(ErrorCode::kInvalidMesh, source.surface.label + ": the rig has no skin (nothing to transfer "
                                                                     "weights or joints from); turn weights/joints off");
  }
  return Ok{};
}

// Every stage after the correspondence (`t_start`: when the transfer began).
Result<TransferResult> transferThroughCorrespondence(const PreparedRig& source, WarpResult correspondence,
                                                     const TransferOptions& options, Clock::time_point t_start) {
  const WarpResult* warp = &correspondence;
  const std::string& target_label = warp->target.label;
  const Rig& src = source.rig;
  // Stage boundaries: where a caller may stop the job (cancellation, time limit).
  auto stopBefore = [&](std::string_view stage, double fraction) {
    return options.on_stage && !options.on_stage(stage, fraction);
  };
  auto stopped = [&](std::string_view stage) {
    return makeError(ErrorCode::kCancelled, target_label + ": transfer stopped before stage '" + std::string(stage) + "'");
  };
  TransferResult result;
  TransferReport& report = result.report;
  report.warp = warp->report;
  warnUnknownExaggerations(src, options, report);
  report.prepare_ms = source.surface.prepare_ms;
  for (const auto& sp : warp->locations.on_source) report.unlocated_vertices += sp.found() ? 0 : 1;

  // --- dense map products: global similarity and per-vertex adaptation
  if (stopBefore("dense_map", 0.5)) return stopped("dense_map");
  auto t0 = Clock::now();
  auto adaptation = adaptToDenseMap(source, *warp, options, target_label, report);
  if (!adaptation) return adaptation.error();
  report.dense_map_ms = msSince(t0);

  // --- assemble the target rig as we go: the target keeps its topology
  Rig& out = result.rig;
  out.mesh = warp->target.mesh;  // its own normals too: authored hard edges and seams stay as they came
  out.mesh.normals = warp->target.normals;  // the file's, or computed once when it has none
  out.mesh_name = src.mesh_name;
  out.nodes = src.nodes;
  out.mesh_node = src.mesh_node;
  auto inpainting = targetInpainting(src, *warp, options, target_label);
  if (!inpainting) return inpainting.error();

  // --- weights
  if (stopBefore("weights", 0.6)) return stopped("weights");
  t0 = Clock::now();
  TransferredWeights weights;
  if (options.weights) {
    auto w = transferSkinWeights(src.weights, source.surface.mesh.triangles, warp->locations,
                                 warp->target.mesh.vertexCount(), inpainting->laplacian, options.weight_options);
    if (!w) return w.error();
    weights = std::move(*w);
    out.weights = weights.weights;
    report.inpainted_vertices = weights.inpainted_vertices;
    report.pruned_vertices = weights.pruned_vertices;
    report.max_influences = weights.max_influences;
  }
  report.weights_ms = msSince(t0);

  // --- joints
  if (stopBefore("joints", 0.7)) return stopped("joints");
  t0 = Clock::now();
  const bool joints_moved = options.joints && src.skin;
  if (joints_moved) {
    TransferredSkeleton skeleton = transferSkeleton(src, adaptation->dense_map, adaptation->global.rotation);
    out.nodes = std::move(skeleton.nodes);
    out.skin = std::move(skeleton.skin);
    report.joints = static_cast<int>(out.skin->joints.size());
  } else if (options.weights && src.skin) {
    out.skin = src.skin;  // joints left as they are: the transferred weights still name them
  }
  report.joints_ms = msSince(t0);

  // --- animations: on the moved joints, translation keys in their new frames
  if (stopBefore("animations", 0.72)) return stopped("animations");
  t0 = Clock::now();
  if (options.animations) out.animations = transferJointAnimations(src, out.nodes, joints_moved, *adaptation, options);
  report.animations_ms = msSince(t0);

  // --- shapes
  if (stopBefore("shapes", 0.75)) return stopped("shapes");
  t0 = Clock::now();
  transferShapes(source, warp->locations, adaptation->vertex_adaptation, inpainting->mismatchedOrNull(), options, out);
  report.shapes = static_cast<int>(out.morph_targets.size());
  report.shapes_ms = msSince(t0);
  report.animations = static_cast<int>(out.animations.size());

  // --- the rig's other meshes (eyeballs, teeth, lashes): by vertex index through the dense map
  if (stopBefore("parts", 0.8)) return stopped("parts");
  t0 = Clock::now();
  CarriedParts parts = carryParts(
      src.parts, adaptation->dense_map, [&](const Eigen::Vector3d& p) { return adaptation->at(p); },
      adaptation->global.rotation);
  // Eyeballs behind the lids, teeth behind the lips, at rest.
  for (std::string& warning : checkPartsBehindSkin(source.parts_occlusion, src.parts, out.mesh,
                                                   warp->target.landmark_positions, adaptation->global.rotation, parts)) {
    report.warnings.push_back(target_label + ": " + warning);
  }
  out.parts = std::move(parts.parts);
  dropPartChannels(out.parts, options.shapes, out.skin.has_value());
  // Materials: the parts keep theirs, the face's go to the target's triangles.
  out.materials = src.materials;
  out.images = src.images;
  out.triangle_materials = carryTriangleMaterials(src.triangle_materials, out.mesh.triangles, warp->locations.on_source);
  for (std::string& warning : untextureFaceMaterials(out)) report.warnings.push_back(target_label + ": " + warning);
  report.parts = std::move(parts.report);
  report.parts_ms = msSince(t0);

  // --- check the output (and repair unsure vertices), before any UV copies
  t0 = Clock::now();
  if (auto ok = checkAndRepairShapes(source, *warp, inpainting->laplacian, options, out, report); !ok) return ok.error();
  report.quality_ms = msSince(t0);

  // --- attributes (+ diagnostics as data), then the UV layout
  if (stopBefore("attributes", 0.9)) return stopped("attributes");
  t0 = Clock::now();
  if (options.attributes) {
    out.attributes = transferAttributes(source.surface.mesh, src.attributes, warp->locations, inpainting->laplacian,
                                        inpainting->mismatchedOrNull());
  }
  if (options.diagnostic_attributes) addDiagnosticAttributes(warp->locations, weights, report.quality, out);
  report.attributes_ms = msSince(t0);
  // --- the rig's components document (influence objects), then the UV layout
  t0 = Clock::now();
  if (source.components) {
    const ComponentsCorrespondence map{source.surface.mesh,        adaptation->dense_map, warp->target.mesh,
                                       warp->target.index,         warp->locations,       inpainting->laplacian,
                                       inpainting->mismatchedOrNull(), adaptation->global.rotation, report.global_scale};
    result.components = transferComponents(*source.components, map);
  }
  report.components_ms = msSince(t0);
  t0 = Clock::now();
  if (auto ok = transferUvs(source, *warp, options, out, report, result.components); !ok) return ok.error();
  report.attributes_ms += msSince(t0);
  report.total_ms = msSince(t_start);
  return result;
}

}  // namespace

WarpOptions transferWarpOptions(const TransferOptions& options) {
  WarpOptions warp_options = options.warp;
  warp_options.full_guide = false;
  return warp_options;
}

Result<TransferResult> transferRig(const PreparedRig& source, PreparedTarget prepared_target,
                                   const TransferOptions& options) {
  const auto t_start = Clock::now();
  if (auto ok = checkSourceSkin(source, options); !ok) return ok.error();
  if (options.on_stage && !options.on_stage("warp", 0.0)) {
    return makeError(ErrorCode::kCancelled, prepared_target.label + ": transfer stopped before stage 'warp'");
  }
  auto warp = runWarp(source.surface, std::move(prepared_target), transferWarpOptions(options));
  if (!warp) return warp.error();
  return transferThroughCorrespondence(source, std::move(*warp), options, t_start);
}

Result<TransferResult> transferRig(const PreparedRig& source, WarpResult correspondence, const TransferOptions& options) {
  if (auto ok = checkSourceSkin(source, options); !ok) return ok.error();
  return transferThroughCorrespondence(source, std::move(correspondence), options, Clock::now());
}

}  // namespace core
