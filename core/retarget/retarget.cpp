// Facial mocap retargeting by RBF with Euclidean, geodesic and hybrid
// distances. Papers: 002 (Ramos Carretero 2019, "AnimFace") chapters 4-5:
// eq. 5.1, algorithm 4.1 (marker transfer; here with a similarity + TPS
// Jacobian calibration instead of 1:1 offsets: calibration.cpp), algorithm
// 4.2 (per-frame RBF; here all frames in one solve). The distances
// (algorithms 5.3-5.4) are in marker_distances.cpp, the bake into morph
// targets in bake.cpp; retarget_stages.h lists the stages in order.
#include "core/retarget/retarget.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/base/timing.h"
#include "core/retarget/retarget_stages.h"

namespace core {

namespace {

Error invalidArgument(const std::string& message) { return makeError(ErrorCode::kInvalidArgument, message); }

// Why the job cannot run on these inputs, checked before any work.
Status checkRetargetInputs(const Mesh& mesh, const MarkerDistances& distances, const MarkerTrajectories& clip,
                           const RetargetOptions& options) {
  const Eigen::Index nv = mesh.vertexCount();
  const Eigen::Index nm = static_cast<Eigen::Index>(distances.marker_names.size());
  const int nf = clip.frameCount();
  if (distances.vertex_marker.rows() != nv || distances.vertex_marker.cols() != nm) {
    return invalidArgument("retarget: the marker distances were made on another mesh (" +
                           std::to_string(distances.vertex_marker.rows()) + " vertices, this one has " +
                           std::to_string(nv) + ")");
  }
  if (nf < 1) return invalidArgument("retarget: the clip has no frames");
  if (clip.positions.cols() != 3 * clip.markerCount()) {
    return invalidArgument("retarget: the clip has " + std::to_string(clip.positions.cols()) + " columns for " +
                           std::to_string(clip.markerCount()) + " markers");
  }
  if (!(clip.data_rate > 0.0 && std::isfinite(clip.data_rate))) {
    return invalidArgument("retarget: the clip's data rate " + std::to_string(clip.data_rate) + " is not > 0");
  }
  if (!clip.positions.allFinite()) return invalidArgument("retarget: the clip has non-finite marker positions");
  if (options.rest_frame < 0 || options.rest_frame >= nf) {
    return invalidArgument("retarget: rest frame " + std::to_string(options.rest_frame) + " is not in the clip's " +
                           std::to_string(nf) + " frames");
  }
  if (options.bake.exact && nf > options.bake.max_exact_frames) {
    return invalidArgument("retarget: exact per-frame output of " + std::to_string(nf) + " frames exceeds " +
                           std::to_string(options.bake.max_exact_frames) + " (use the compressed bake)");
  }
  if (!(options.bake.tolerance >= 0.0) || options.bake.max_rank < 1) {
    return invalidArgument("retarget: bake tolerance must be >= 0 and max_rank >= 1");
  }
  return Ok{};
}

// The placed markers by name in the clip.
struct MarkersInClip {
  std::vector<int> column;            // #M: the marker's index in the clip, -1 when absent
  std::vector<Eigen::Index> present;  // placed markers the clip carries, ascending
  std::vector<std::string> absent;    // names of those it does not
};

MarkersInClip findMarkersInClip(const MarkerDistances& distances, const MarkerTrajectories& clip) {
  const Eigen::Index nm = static_cast<Eigen::Index>(distances.marker_names.size());
  MarkersInClip out;
  out.column.resize(static_cast<std::size_t>(nm));
  for (Eigen::Index i = 0; i < nm; ++i) {
    const std::string& name = distances.marker_names[static_cast<std::size_t>(i)];
    out.column[static_cast<std::size_t>(i)] = clip.markerIndex(name);
    if (out.column[static_cast<std::size_t>(i)] >= 0) {
      out.present.push_back(i);
    } else {
      out.absent.push_back(name);
    }
  }
  return out;
}

// The clip's markers that are not placed on the mesh, in the clip's order.
std::vector<std::string> unusedClipMarkers(const MarkerTrajectories& clip, const std::vector<int>& column) {
  std::vector<std::string> unused;
  for (std::size_t c = 0; c < clip.marker_names.size(); ++c) {
    if (std::find(column.begin(), column.end(), static_cast<int>(c)) == column.end()) {
      unused.push_back(clip.marker_names[c]);
    }
  }
  return unused;
}

// The distances of the markers `present` only, in that order.
MarkerDistances keepMarkers(const MarkerDistances& distances, const std::vector<Eigen::Index>& present) {
  MarkerDistances carried = distances;
  carried.marker_names.clear();
  carried.marker_positions.resize(static_cast<Eigen::Index>(present.size()), 3);
  carried.marker_marker.resize(carried.marker_positions.rows(), carried.marker_positions.rows());
  carried.vertex_marker.resize(distances.vertex_marker.rows(), carried.marker_positions.rows());
  for (std::size_t a = 0; a < present.size(); ++a) {
    const auto ia = static_cast<Eigen::Index>(a);
    carried.marker_names.push_back(distances.marker_names[static_cast<std::size_t>(present[a])]);
    carried.marker_positions.row(ia) = distances.marker_positions.row(present[a]);
    carried.vertex_marker.col(ia) = distances.vertex_marker.col(present[a]);
    for (std::size_t b = 0; b < present.size(); ++b) {
      carried.marker_marker(ia, static_cast<Eigen::Index>(b)) = distances.marker_marker(present[a], present[b]);
    }
  }
  return carried;
}

// Placed markers the clip does not carry (one lost in the session, a
// placement shared by several sessions): the others drive the mesh, and the
// report names the absent ones.
Result<RetargetOutput> retargetMarkersInClip(const Mesh& mesh, const MarkerDistances& distances,
                                             const MarkerTrajectories& clip, const RetargetOptions& options,
                                             const MarkersInClip& in_clip) {
  if (in_clip.present.empty()) {
    return makeError(ErrorCode::kInvalidLandmarks, "retarget: none of the " +
                                                       std::to_string(distances.marker_names.size()) +
                                                       " placed markers is in the clip (placed: " +
                                                       joinNames(in_clip.absent) + ")");
  }
  RetargetOptions carried_options = options;
  for (const std::string& name : in_clip.absent) {
    carried_options.stiffness.erase(name);
    std::erase(carried_options.head_markers, name);
  }
  auto out = retargetMocap(mesh, keepMarkers(distances, in_clip.present), clip, carried_options);
  if (out) out->report.markers_not_in_clip = in_clip.absent;
  return out;
}

// The RBF of the job: gamma from the mesh's size unless given, a constant
// polynomial instead of an affine one on surface distances, stiffness by
// marker name.
Result<RbfOptions> markerRbfOptions(const MarkerDistances& distances, const RetargetOptions& options) {
  RbfOptions rbf;
  rbf.kernel = options.kernel;
  rbf.gamma = options.gamma > 0.0 ? options.gamma : kDefaultGammaFactor * distances.mesh_diagonal;
  rbf.polynomial = options.polynomial;
  const bool euclidean = distances.method == DistanceMethod::kEuclidean;
  if (!euclidean && rbf.polynomial == RbfPolynomial::kAffine) rbf.polynomial = RbfPolynomial::kConstant;
  rbf.stiffness_step = options.stiffness_step;
  if (!options.stiffness.empty()) {
    rbf.stiffness.assign(distances.marker_names.size(), 1.0);
    for (const auto& [name, s] : options.stiffness) {
      const auto it = std::find(distances.marker_names.begin(), distances.marker_names.end(), name);
      if (it == distances.marker_names.end()) return invalidArgument("retarget: stiffness for unknown marker " + name);
      rbf.stiffness[static_cast<std::size_t>(it - distances.marker_names.begin())] = s;
    }
  }
  return rbf;
}

// The factorised marker system and its basis on the mesh's vertices.
struct MarkerSystem {
  RbfFactorization factorization;
  Eigen::MatrixXd basis;  // #V by #K
};

Result<MarkerSystem> factoriseMarkers(const Mesh& mesh, const MarkerDistances& distances, const RbfOptions& rbf) {
  const bool euclidean = distances.method == DistanceMethod::kEuclidean;
  const Eigen::MatrixX3d no_positions;
  auto factorization = RbfFactorization::create(distances.marker_marker, euclidean ? distances.marker_positions : no_positions, rbf);
  if (!factorization) return factorization.error();
  auto basis = factorization->basis(distances.vertex_marker, mesh.positions);
  if (!basis) return basis.error();
  return MarkerSystem{std::move(*factorization), std::move(*basis)};
}

// The RBF at the markers against the displacements it interpolates, model units.
struct MarkerResiduals {
  double max = 0.0;
  double rms = 0.0;
};

MarkerResiduals markerResiduals(const RbfFactorization& factorization, const Eigen::MatrixXd& weights,
                                const Eigen::MatrixXd& rhs) {
  const Eigen::Index nm = rhs.rows();
  const int nf = static_cast<int>(rhs.cols() / 3);
  const Eigen::MatrixXd at_markers = RbfFactorization::evaluate(factorization.centreBasis(), weights) - rhs;
  MarkerResiduals out;
  double sum2 = 0.0;
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) {
      const double e2 = at_markers.block(i, 3 * f, 1, 3).squaredNorm();
      sum2 += e2;
      out.max = std::max(out.max, std::sqrt(e2));
    }
  }
  out.rms = std::sqrt(sum2 / static_cast<double>(nm * nf));
  return out;
}

// The rig before the bake: the mesh (with normals), one node carrying it.
Rig meshRig(const Mesh& mesh, const std::string& mesh_name) {
  Rig rig;
  rig.mesh = mesh;
  if (rig.mesh.normals.rows() != mesh.vertexCount()) {
    rig.mesh.normals = computeSeamlessVertexNormals(mesh.positions, mesh.triangles);
  }
  rig.mesh_name = mesh_name;
  Node node;
  node.name = mesh_name;
  rig.nodes.push_back(node);
  rig.mesh_node = 0;
  return rig;
}

// The rig with the baked morph targets and one animation of their weights,
// a key per frame of the clip.
Rig addMocapAnimation(Rig rig, std::vector<MorphTarget> targets, Eigen::MatrixXd frame_weights, int frames,
                      double data_rate, const std::string& animation_name) {
  rig.morph_targets = std::move(targets);
  AnimationChannel channel;
  channel.node = 0;
  channel.path = AnimationPath::kWeights;
  channel.interpolation = Interpolation::kLinear;
  channel.times = Eigen::VectorXd::LinSpaced(frames, 0.0, (frames - 1) / data_rate);
  channel.values = std::move(frame_weights);
  rig.morph_default_weights = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(rig.morph_targets.size()));
  Animation animation;
  animation.name = animation_name;
  animation.channels.push_back(std::move(channel));
  rig.animations.push_back(std::move(animation));
  return rig;
}

// The report of a job: the bake's (`report`) completed from the inputs and
// the products of the other stages.
RetargetReport assembleReport(RetargetReport report, const MarkerDistances& distances, const MarkerTrajectories& clip,
                              const RetargetOptions& options, const std::vector<int>& column,
                              const CalibratedClip& calibrated, const RbfOptions& rbf,
                              const RbfFactorization& factorization, const MarkerResiduals& residuals) {
  report.method = distances.method;
  report.kernel = options.kernel;
  report.frames = clip.frameCount();
  report.markers = static_cast<int>(distances.marker_names.size());
  report.vertices = static_cast<int>(distances.vertex_marker.rows());
  report.data_rate = clip.data_rate;
  report.filled_gaps = clip.filled_gaps;
  report.rest_frame = options.rest_frame;
  report.mocap_units_to_metres = clip.units_to_metres;
  report.mesh_diagonal = distances.mesh_diagonal;
  report.regions = distances.regions;
  report.boundary_loops = distances.boundary_loops;
  report.unused_clip_markers = unusedClipMarkers(clip, column);

  report.similarity_scale = calibrated.calibration.similarity.scale;
  report.similarity_rms = calibrated.calibration.similarity_rms;
  report.jacobian_min_singular = calibrated.calibration.min_singular;
  report.jacobian_max_singular = calibrated.calibration.max_singular;
  for (Eigen::Index h : calibrated.head) report.head_markers.push_back(distances.marker_names[static_cast<std::size_t>(h)]);
  report.head_motion_removed = options.remove_head_motion;
  report.head_max_rotation_deg = calibrated.displacements.head_max_rotation_deg;
  report.head_max_translation = calibrated.displacements.head_max_translation;
  report.max_marker_displacement = calibrated.displacements.max_marker_displacement;

  report.gamma = rbf.gamma;
  report.polynomial_terms = factorization.polynomialTerms();
  report.condition = factorization.conditionEstimate();
  report.marker_max_residual = residuals.max;
  report.marker_rms_residual = residuals.rms;
  report.tolerance = options.bake.tolerance;
  return report;
}

// #frames by 3#M: the displacements a frame to a row (x0 y0 z0 x1 ...).
Eigen::MatrixXd displacementsByFrame(const Eigen::MatrixXd& rhs) {
  const Eigen::Index nm = rhs.rows();
  const int nf = static_cast<int>(rhs.cols() / 3);
  Eigen::MatrixXd marker_displacements(nf, 3 * nm);
  for (int f = 0; f < nf; ++f) {
    for (Eigen::Index i = 0; i < nm; ++i) marker_displacements.block(f, 3 * i, 1, 3) = rhs.block(i, 3 * f, 1, 3);
  }
  return marker_displacements;
}

}  // namespace

Result<RetargetOutput> retargetMocap(const Mesh& mesh, const MarkerDistances& distances, const MarkerTrajectories& clip,
                                     const RetargetOptions& options) {
  const auto t_start = Clock::now();
  if (Status valid = checkRetargetInputs(mesh, distances, clip, options); !valid) return valid.error();
  const MarkersInClip in_clip = findMarkersInClip(distances, clip);
  if (!in_clip.absent.empty()) return retargetMarkersInClip(mesh, distances, clip, options, in_clip);
  std::map<std::string, double> timings_ms{{"distances", 0.0}};  // cached; the one-off overload fills it in

  auto t0 = Clock::now();
  auto calibrated = calibrateClip(distances, clip, in_clip.column, options);
  if (!calibrated) return calibrated.error();
  const Eigen::MatrixXd& rhs = calibrated->displacements.rhs;
  timings_ms["calibrate"] = msSince(t0);

  // Factorise the marker system.
  t0 = Clock::now();
  auto rbf = markerRbfOptions(distances, options);
  if (!rbf) return rbf.error();
  auto system = factoriseMarkers(mesh, distances, *rbf);
  if (!system) return system.error();
  timings_ms["factorise"] = msSince(t0);

  // Solve all frames at once.
  t0 = Clock::now();
  const Eigen::MatrixXd weights = system->factorization.solve(rhs);  // #K by 3F
  timings_ms["solve"] = msSince(t0);

  // Evaluate at the markers (interpolation residual) and bake.
  t0 = Clock::now();
  const MarkerResiduals residuals = markerResiduals(system->factorization, weights, rhs);
  const double residuals_ms = msSince(t0);
  Rig rig = meshRig(mesh, options.mesh_name);
  BakedMotion baked = options.bake.exact ? bakeFrames(system->basis, weights)
                                         : bakeModes(system->basis, weights, options.bake);
  t0 = Clock::now();
  rig = addMocapAnimation(std::move(rig), std::move(baked.targets), std::move(baked.frame_weights), clip.frameCount(),
                          clip.data_rate, options.animation_name);
  timings_ms["evaluate"] = residuals_ms + baked.evaluate_ms;
  timings_ms["bake"] = baked.bake_ms + msSince(t0);

  RetargetReport report = assembleReport(std::move(baked.report), distances, clip, options, in_clip.column,
                                         *calibrated, *rbf, system->factorization, residuals);
  report.timings_ms = std::move(timings_ms);
  report.total_ms = msSince(t_start);
  return RetargetOutput{std::move(rig), std::move(report), displacementsByFrame(rhs)};
}

Result<RetargetOutput> retargetMocap(const Mesh& mesh, const LandmarkSet& markers, const MarkerTrajectories& clip,
                                     const std::string& label, const MarkerDistanceOptions& distance_options,
                                     const RetargetOptions& options) {
  auto distances = computeMarkerDistances(mesh, markers, label, distance_options);
  if (!distances) return distances.error();
  auto out = retargetMocap(mesh, *distances, clip, options);
  if (out) {
    out->report.timings_ms["distances"] = distances->compute_ms;
    out->report.total_ms += distances->compute_ms;
  }
  return out;
}

std::string formatRetargetDiagnostics(const RetargetReport& r, const std::map<std::string, double>& extra_timings_ms,
                                      double total_ms) {
  using Json = nlohmann::ordered_json;
  Json doc;
  doc["method"] = distanceMethodName(r.method);
  doc["kernel"] = rbfKernelName(r.kernel);
  doc["gamma"] = r.gamma;
  doc["polynomial_terms"] = r.polynomial_terms;
  doc["condition"] = r.condition;
  doc["counts"] = {{"frames", r.frames}, {"markers", r.markers}, {"vertices", r.vertices}, {"data_rate", r.data_rate},
                   {"rest_frame", r.rest_frame}, {"unused_clip_markers", r.unused_clip_markers},
                   {"markers_not_in_clip", r.markers_not_in_clip}};
  doc["calibration"] = {{"mocap_units_to_metres", r.mocap_units_to_metres},
                        {"similarity_scale", r.similarity_scale},
                        {"similarity_rms", r.similarity_rms},
                        {"jacobian_min_singular", r.jacobian_min_singular},
                        {"jacobian_max_singular", r.jacobian_max_singular},
                        {"max_marker_displacement", r.max_marker_displacement},
                        {"head_motion_removed", r.head_motion_removed},
                        {"head_markers", r.head_markers},
                        {"head_max_rotation_deg", r.head_max_rotation_deg},
                        {"head_max_translation", r.head_max_translation}};
  Json gaps = Json::array();
  for (const TrcGap& g : r.filled_gaps) {
    gaps.push_back({{"marker", g.marker},
                    {"first_frame", g.first_frame},
                    {"frames", g.frame_count},
                    {"fill", g.fill == GapFill::kInterpolated ? "interpolated" : "neighbours"},
                    {"donors", g.donors}});
  }
  doc["gaps"] = gaps;
  doc["interpolation"] = {{"marker_max_residual", r.marker_max_residual}, {"marker_rms_residual", r.marker_rms_residual}};
  const double diag = r.mesh_diagonal > 0.0 ? r.mesh_diagonal : 1.0;
  doc["bake"] = {{"exact", r.exact},
                 {"rank", r.rank},
                 {"tolerance", r.tolerance},
                 {"tolerance_met", r.tolerance_met},
                 {"relative_error", r.relative_error},
                 {"rms_error", r.rms_error},
                 {"rms_error_percent_diagonal", 100.0 * r.rms_error / diag},
                 {"max_error", r.max_error},
                 {"max_error_percent_diagonal", 100.0 * r.max_error / diag},
                 {"max_error_measured", r.max_error_measured},
                 {"mesh_diagonal", r.mesh_diagonal},
                 {"singular_values", r.singular_values}};
  Json regions = Json::array();
  for (const GeodesicRegion& g : r.regions) {
    regions.push_back({{"loop", g.loop},
                       {"loop_vertices", g.loop_vertices},
                       {"extent", g.extent},
                       {"centroid", {g.centroid.x(), g.centroid.y(), g.centroid.z()}},
                       {"region_vertices", g.region_vertices}});
  }
  doc["geodesic_regions"] = {{"boundary_loops", r.boundary_loops}, {"regions", regions}};
  Json& t = doc["timings_ms"];
  for (const char* stage : {"distances", "calibrate", "factorise", "solve", "evaluate", "bake"}) {
    const auto it = r.timings_ms.find(stage);
    t[stage] = it != r.timings_ms.end() ? it->second : 0.0;
  }
  for (const auto& [name, ms] : extra_timings_ms) t[name] = ms;
  t["total"] = total_ms >= 0.0 ? total_ms : r.total_ms;
  return doc.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace core
